import numpy as np

from robointel.planning import load_scene, plan_scene
from robointel.teach.streaming import StreamingController
from robointel.teach.teleop import TeleopApp

app = TeleopApp(StreamingController())            # the simulated LR Mate behind the streaming safety checks
app.controller.start()                            # app.start() also serves the browser page on 127.0.0.1:8080
down = [np.cos(np.pi / 4), 0.0, np.sin(np.pi / 4), 0.0]   # hand orientation (w, x, y, z): tool pointing down
for hand in ([0.45, 0.10, 0.40], [0.40, -0.15, 0.30], [0.50, 0.05, 0.25]):   # the operator's hand, m
    assert app.move_hand(hand, down)              # IK, table and self-collision checks, streamed to the arm
    app.record()                                  # keep the target as a waypoint
errors = app.replay()                             # drive the arm through the taught waypoints again
app.controller.stop()
print(f"replayed {len(errors)} waypoints, largest error {max(errors) * 1e3:.2f} mrad")

path = app.save("taught_program.yaml")            # robot, table, waypoints: a planning scene
plan = plan_scene(load_scene(path))               # a smooth, collision-free, time-optimised trajectory
print(f"planned {plan.trajectory.duration:.2f} s of motion through the taught waypoints")
