"""A FANUC controller without hardware (docs/guides/fanuc.md): the emulator command, and a bad host."""
import signal
import subprocess


def test_the_emulator_serves_a_program_and_stops_cleanly_on_ctrl_c(robointel, robointel_command, tmp_path):
    emu = subprocess.Popen([*robointel_command, "emulator"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        url = ""
        for line in emu.stdout:
            if line.startswith("robot URL: "):
                url = line.split(": ", 1)[1].strip()
                break
        assert url.startswith("fanuc://127.0.0.1:"), url
        r = robointel("run", "moves_fanuc", "--robot", url, "--report", str(tmp_path / "report"))
        assert r.returncode == 0, r.stderr
        emu.send_signal(signal.SIGINT)
        out, err = emu.communicate(timeout=60)
    finally:
        if emu.poll() is None:
            emu.kill()
    assert emu.returncode == 0, err
    assert "stopped: 0 conformance violations" in out, out
    assert "Traceback" not in err and "EOFError" not in err, err


def test_a_host_with_no_controller_gives_one_line_and_exit_code_2(robointel):
    for url in ("fanuc://192.168.1.10", "fanuc://127.0.0.1:1?sm_port=2"):
        r = robointel("run", "moves_fanuc", "--robot", url, timeout=300)
        lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
        assert r.returncode == 2 and len(lines) == 1, r.stderr
        assert lines[0].startswith(f"error: could not bring up the FANUC controller at {url[8:].split('?')[0]}")
        assert "Traceback" not in r.stdout + r.stderr
    assert "port 1 closed on 127.0.0.1" in lines[0]
