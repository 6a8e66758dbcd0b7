"""One colour per estimator, shared by plots and Rerun recordings."""

from __future__ import annotations

COLORS: dict[str, tuple[int, int, int]] = {
    "truth": (120, 120, 120),
    "odometry": (230, 140, 20),
    "ekf": (30, 110, 220),
    "smoother": (20, 160, 80),
    "batch": (150, 60, 190),
    "observations": (200, 60, 60),
}
"""RGB colours by estimator name."""

_EXTRA = [(0, 150, 150), (200, 50, 120), (120, 120, 0), (110, 70, 30), (70, 70, 170), (230, 90, 50), (0, 90, 60)]


def rgb_colors(names: list[str] | tuple[str, ...]) -> dict[str, tuple[int, int, int]]:
    """0-255 RGB per estimator: the fixed ones above, then distinct colours in order of appearance."""
    out, extra = {}, 0
    for name in names:
        if name in COLORS:
            out[name] = COLORS[name]
        else:
            out[name], extra = _EXTRA[extra % len(_EXTRA)], extra + 1
    return out


def palette(names: list[str]) -> dict[str, tuple[float, float, float]]:
    """Matplotlib colours (0-1 RGB) for these estimators, as :func:`rgb_colors`."""
    return {name: (r / 255, g / 255, b / 255) for name, (r, g, b) in rgb_colors(names).items()}
