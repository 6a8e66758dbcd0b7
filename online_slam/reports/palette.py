"""One colour per estimator, shared by plots and Rerun recordings.

The colours are Okabe and Ito's qualitative palette ("Color Universal Design", 2002), which stays distinct
under the common colour-vision deficiencies; plots add a line style per estimator on top of it.
"""

from __future__ import annotations

OKABE_ITO: dict[str, tuple[int, int, int]] = {
    "orange": (230, 159, 0),
    "sky blue": (86, 180, 233),
    "bluish green": (0, 158, 115),
    "yellow": (240, 228, 66),
    "blue": (0, 114, 178),
    "vermillion": (213, 94, 0),
    "reddish purple": (204, 121, 167),
}
"""The palette's colours (its black is left out: it would vanish on the Rerun viewer's dark background)."""

COLORS: dict[str, tuple[int, int, int]] = {
    "truth": (120, 120, 120),
    "odometry": OKABE_ITO["orange"],
    "ekf": OKABE_ITO["blue"],
    "smoother": OKABE_ITO["vermillion"],
    "batch": OKABE_ITO["reddish purple"],
    "observations": OKABE_ITO["yellow"],
}
"""RGB colours by estimator name."""

_EXTRA = [OKABE_ITO["bluish green"], OKABE_ITO["sky blue"], (110, 70, 30), (70, 70, 170), (0, 90, 60)]


def rgb_colors(names: list[str] | tuple[str, ...]) -> dict[str, tuple[int, int, int]]:
    """0-255 RGB per estimator: the fixed ones above, then further smoothers in order of appearance.

    The first smoother configuration without a colour of its own takes the smoother's vermillion, so that the
    usual comparison (EKF, one smoother, batch) shows the same colours whatever the smoother's label says.
    """
    out: dict[str, tuple[int, int, int]] = {}
    taken = {COLORS[name] for name in names if name in COLORS}
    free = [c for c in (COLORS["smoother"], *_EXTRA) if c not in taken]
    for name in names:
        if name in COLORS:
            out[name] = COLORS[name]
        else:
            out[name] = free[0] if free else _EXTRA[len(out) % len(_EXTRA)]
            free = free[1:]
    return out


def palette(names: list[str]) -> dict[str, tuple[float, float, float]]:
    """Matplotlib colours (0-1 RGB) for these estimators, as :func:`rgb_colors`."""
    return {name: (r / 255, g / 255, b / 255) for name, (r, g, b) in rgb_colors(names).items()}
