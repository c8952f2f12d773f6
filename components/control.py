"""Cold control data: what the pilot (or a script) asks for, and what the ship can do.

These are plain dataclasses: one or a few controlled bodies per scene, so the
control systems may loop over them in Python.
"""
from __future__ import annotations

from dataclasses import dataclass

from driftframe.framework import validate
from driftframe.framework.input import CHANNELS

MODES = ("direct", "momentum")
ASSIST_AXES = ("all", "roll", "pitch", "yaw", "sequential")


class Player:
    """Marker: the entity the keyboard flies and the cameras follow by default."""


@dataclass
class FlightInput:
    """The pilot's intent this step, each channel in [-1, 1] (written by input or a script).

    ``throttle``: + along the local forward axis. ``roll``: about local
    forward; ``pitch``: about local right; ``yaw``: about local up (right-hand
    rule). ``kill_rotation``: engage the rotation assist.
    """

    throttle: float = 0.0
    roll: float = 0.0
    pitch: float = 0.0
    yaw: float = 0.0
    kill_rotation: bool = False

    def __post_init__(self):
        for name in CHANNELS:
            setattr(self, name, validate.scalar(f"FlightInput.{name}", getattr(self, name), lo=-1.0, hi=1.0))
        self.kill_rotation = bool(self.kill_rotation)


@dataclass
class FlightControl:
    """What the ship can do with the input.

    ``mode``: ``"direct"`` (turns only while input is held, at ``turn_rate``)
    or ``"momentum"`` (input is angular acceleration; spin persists).
    """

    #: "direct" or "momentum".
    mode: str = "momentum"
    #: Thrust acceleration at full throttle, m/s^2 (along local forward).
    thrust: float = 10.0
    #: Direct mode: spin rate at full input about each local axis, rad/s.
    turn_rate: float = 1.5
    #: Momentum mode: angular acceleration at full input, rad/s^2.
    angular_accel: float = 2.0

    def __post_init__(self):
        validate.choice("FlightControl.mode", self.mode, MODES)
        self.thrust = validate.scalar("FlightControl.thrust", self.thrust, nonnegative=True)
        self.turn_rate = validate.scalar("FlightControl.turn_rate", self.turn_rate, nonnegative=True)
        self.angular_accel = validate.scalar("FlightControl.angular_accel", self.angular_accel, nonnegative=True)


@dataclass
class RotationAssist:
    """Kill-rotation assist: removes spin at a bounded angular deceleration while engaged.

    ``axes``: ``"all"`` (brake the whole spin vector along itself),
    ``"roll"``/``"pitch"``/``"yaw"`` (brake that local axis only), or
    ``"sequential"`` (roll, then pitch, then yaw: one local axis at a time).
    It stops exactly at zero: the last step removes only what is left.
    """

    #: Largest angular deceleration, rad/s^2.
    max_decel: float = 3.0
    axes: str = "all"
    #: Engaged without input (e.g. a script); FlightInput.kill_rotation also engages it.
    engaged: bool = False

    def __post_init__(self):
        self.max_decel = validate.scalar("RotationAssist.max_decel", self.max_decel, positive=True)
        validate.choice("RotationAssist.axes", self.axes, ASSIST_AXES)
