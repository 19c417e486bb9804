from robointel.interface import open_robot
from robointel.planning import load_scene, plan_scene
from robointel.testing.emulator import fanuc_url, running_fake


def main() -> None:
    traj = plan_scene(load_scene("table71")).trajectory   # the LR Mate cell of the dissertation's Table 7.1
    with running_fake(q0=traj.q[0]) as controller:         # a FANUC controller emulator on 127.0.0.1
        for url in ("sim", fanuc_url(controller)):         # a real arm: open_robot("fanuc://192.168.1.10")
            with open_robot(url) as arm:
                arm.move_to(traj.q[0])                     # a quintic move to the start at 20 % of the limits
                run = arm.execute(traj)                    # streamed every arm.period (8 ms), supervised
                print(f"{url.split(':')[0]}: completed {run.completed}, "
                      f"tracking RMS {run.tracking_rms_rad:.4f} rad")


if __name__ == "__main__":                                 # the emulator runs in a process of its own
    main()
