"""MuJoCo worlds built from the robot description: scenes, sensors, controllers (Ch. 2).

Public API:

* :class:`Workcell` - the robot on a table in MuJoCo with obstacles, objects, a flange F/T sensor
  and the Fig. 2.3 joint controller; :class:`TrackingLog`, :class:`Contact`, :class:`FTSensor`.
* :class:`Payload`, :class:`SimObject` - a tool after the F/T sensor; a free body.
* :class:`JointController`, :class:`PIDGains` - decentralised PID + model-based feed-forward.
* :class:`FlexibleJointModel`, :class:`FlexibleJointParams` - the flexible-joint model (2.1)-(2.2).
* :func:`build_spec`, :func:`build_model` - the MuJoCo model from the robot's own URDF.
"""
from robointel.control.servo import JointController, PIDGains, model_with_payload
from robointel.sim.flexible import FlexibleJointModel, FlexibleJointParams
from robointel.sim.mjcf import TABLE_HEIGHT, Payload, SimObject, build_model, build_spec
from robointel.sim.workcell import CONTROL_DT, Contact, FTSensor, TrackingLog, Workcell

__all__ = ["Workcell", "TrackingLog", "Contact", "FTSensor", "Payload", "SimObject", "JointController",
           "PIDGains", "model_with_payload", "FlexibleJointModel", "FlexibleJointParams", "build_spec",
           "build_model", "TABLE_HEIGHT", "CONTROL_DT"]
