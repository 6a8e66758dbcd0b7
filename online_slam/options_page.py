"""The docs' option list (``docs/options.md``), rendered from the option table of :mod:`online_slam.options`."""

from __future__ import annotations

from online_slam.options import ADVANCED, GROUPS, OPTIONS


def markdown() -> str:
    """The docs' option list (``docs/options.md``), rendered from the table."""
    lines = [
        "# Options",
        "",
        "Generated from the option table in `online_slam/options.py` (its docstring says how); a test checks",
        "that this page equals the rendering. Each option is a flag of the commands listed (`--window-distance`)",
        'and, for the estimator options, a keyword of `Slam` (`Slam("smoother", window_distance=10.0)`) and a',
        "comma-separated list of `sweep` (every combination runs). `compare --window` and",
        "`compare --relinearize-every` take lists too: one smoother per (W, K), each row labelled with what ran",
        "(`smoother W=20..120 D=18 K=1 invariant`: at least 20 poses, more until the window's path is 18 m, at",
        "most 120, with the invariant prior; `smoother W=5 K=1` with",
        "`--window-distance 0 --smoother-linearization standard`: exactly 5 poses, the standard prior).",
        "",
        "Owners: `ekf`, `smoother`, `batch`, `front-end` (how events become steps) and `association` configure the",
        "estimators (a `Slam` takes those of its estimator, the front-end's and the association's); `dataset`",
        "options read files; `replay` options choose what runs and how it is scored; `cli` options are about",
        "output, live viewing, checkpoints and runs.",
    ]
    for group in GROUPS:
        members = [o for o in OPTIONS.values() if o.group == group]
        lines += ["", f"## {group}", "", "| option | type | default | owner | commands | what it does |"]
        lines.append("|---|---|---|---|---|---|")
        for o in members:
            kind = " \\| ".join(f"`{c}`" for c in o.choices) if o.choices else o.kind.__name__
            slam = o.estimator and (o.fits("ekf") or o.fits("smoother"))
            commands = ", ".join((*o.commands, "Slam") if slam else o.commands)
            shown, owners = o.shown_default() or "-", ", ".join(o.owners)
            flags = ", ".join(f"`{f}`" for f in (o.short, o.flag) if f)
            told = ("advanced (`--help-all`): " if o.name in ADVANCED else "") + o.help
            row = (flags, kind, shown, owners, commands, told.replace("|", "\\|"))
            lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines) + "\n"
