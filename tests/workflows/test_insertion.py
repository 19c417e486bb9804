"""Insertion, one path (docs/guides/cli.md): learn the felt skill into a skill file, insert with it at 20 um."""
import json


def test_the_learned_skill_inserts_at_20_um_from_the_cli(robointel, tmp_path):
    skill = tmp_path / "peg.skill.h5"
    # three demonstrations instead of the default ten keep the test short; the path is the documented one
    r = robointel("learn", "insertion", "--demos", "3", "--trials", "0", "--out", str(tmp_path), "--skill-out",
                  str(skill))
    assert r.returncode == 0, r.stderr
    assert skill.is_file() and f"skill insert --skill {skill}" in " ".join(r.stdout.split())
    r = robointel("skill", "insert", "--skill", str(skill), "--trials", "1", "--seed", "7", "--json",
                  str(tmp_path / "run.json"))
    assert r.returncode == 0, r.stderr
    out = json.loads((tmp_path / "run.json").read_text())
    assert out["strategy"] == "felt" and out["clearance_m"] == 20e-6 and out["time_limit_s"] == 15.0
    assert out["seated"] == 1, out
    assert out["trials"][0]["max_penetration_m"] < 10e-6  # seated without pressing into the 20 um wall
