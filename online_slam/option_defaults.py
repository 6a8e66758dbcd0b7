"""The defaults of the options read from configuration fields, and choices defined beside them.

Generated from the dataclasses by :func:`online_slam.options.defaults_module` (its module docstring says
how) so that ``--help`` needs no numerical library; tests/test_options.py checks it is current.
"""

from __future__ import annotations

import math

DEFAULTS: dict[str, object] = {
    "odometry_noise_scale": 1.0,
    "sensor_noise_scale": 1.0,
    "estimators": ("ekf", "smoother", "batch"),
    "align": "anchor",
    "first_observation_only": False,
    "keyframe_distance": 0.5,
    "keyframe_angle": 0.35,
    "keyframe_time": math.inf,
    "batch_init": "auto",
    "max_iterations": 100,
    "gate_probability": 0.9999,
    "gate_persistence": 8,
    "ekf_update": "joint",
    "ekf_linearization": "invariant",
    "window": 20,
    "window_distance": 18.0,
    "window_max": 120,
    "relinearize_every": 1,
    "global_every": 200,
    "global_delay": 50,
    "smoother_linearization": "invariant",
    "global_information_max": 0,
    "association": "auto",
    "new_density": 0.0,
    "robust_scale": 1.345,
    "checkpoint_every": 100,
    "runs": 1,
}
"""Default of each option that reads a configuration field, by option name."""
CHOICES: dict[str, tuple[str, ...]] = {
    "association": ("known", "nn", "jcbb"),
    "robust": ("auto", "none", "huber", "cauchy"),
    "ekf_linearization": ("standard", "fej", "oc", "invariant"),
    "smoother_linearization": ("standard", "fej", "invariant"),
    "peer": ("isam2",),
}
"""Allowed values of the options whose choices the estimators define."""
