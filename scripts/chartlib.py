"""Shared matplotlib helpers for scripts/charts, scripts/chart-dag and scripts/chart-chunk-target.

matplotlib (Debian python3-matplotlib, installed by scripts/setup) with the Agg backend; SVG text stays text
(svg.fonttype none) and the SVG carries no date and hashes ids with a fixed salt, so the same input gives a
byte-identical file.
"""
import math
import os
import sys

try:
    import matplotlib
except ImportError:
    sys.exit("%s: needs matplotlib (Debian python3-matplotlib, scripts/setup installs it); this python3 is %s"
             % (os.path.basename(sys.argv[0]), sys.executable))

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402
from matplotlib.ticker import FuncFormatter, LogLocator, MaxNLocator, NullFormatter, NullLocator  # noqa: E402

plt.rcParams.update({"svg.hashsalt": "rtpack", "svg.fonttype": "none", "font.family": "sans-serif",
                     "font.size": 10, "axes.spines.top": False, "axes.spines.right": False})
DASH, DOT = "--", ":"  # the old charts' stroke-dasharray 6,4 and 2,3


def figure(w=8.0, h=4.5, right=0.72, left=0.12, ncols=1, nrows=1):
    """A figure with room on the right for the legend and on top for a title and a subtitle."""
    fig, ax = plt.subplots(nrows, ncols, figsize=(w, h))
    fig.subplots_adjust(left=left, right=right, top=0.84 if nrows == 1 else 0.9, bottom=0.14 if nrows == 1 else 0.08,
                        wspace=0.35, hspace=0.35)
    return fig, ax


def titles(fig, title, subtitle=None, x=None):
    """Bold title and grey subtitle, centred over the plot area (or at figure fraction x)."""
    if x is None:
        x = (fig.subplotpars.left + fig.subplotpars.right) / 2
    fig.text(x, 0.955, title, ha="center", va="center", fontsize=12, weight="bold")
    if subtitle:
        fig.text(x, 0.905, subtitle, ha="center", va="center", fontsize=9, color="#555555")


def grid(ax):
    ax.set_axisbelow(True)
    ax.yaxis.grid(True, color="#dddddd")


def yformat(ax, fmt):
    """Major y ticks through fmt (a function of the value); minor tick labels off (log axes)."""
    ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _: fmt(v)))
    ax.yaxis.set_minor_formatter(NullFormatter())


def bytes_axis(ax):
    """y ticks at round KiB / MiB values (powers of two on a log axis), labelled "16 KiB"; set the limits first."""
    if ax.get_yscale() == "log":
        ax.yaxis.set_major_locator(LogLocator(base=2, numticks=8))
        ax.yaxis.set_minor_locator(NullLocator())
    else:
        lo, hi = ax.get_ylim()
        unit = 2 ** 20 if hi >= 2 ** 21 else 2 ** 10 if hi >= 2 ** 11 else 1
        ax.set_yticks([t * unit for t in MaxNLocator(6).tick_values(lo / unit, hi / unit) if lo <= t * unit <= hi])
    yformat(ax, lambda v: human(v, "%g"))


def decades(vals):
    """(lo, hi): powers of ten around vals, at least one decade apart."""
    lo = 10 ** math.floor(math.log10(max(min(vals), 1e-12)))
    hi = 10 ** math.ceil(math.log10(max(vals)))
    return lo, hi if hi > lo else lo * 10


def bar(ax, group, i, n, height, color, text=None, width=0.8, bottom=0, size=8):
    """Bar i of n in the group centred on x = group; text (if any) printed above it."""
    bw = width / n
    b = ax.bar(group - width / 2 + (i + 0.5) * bw, height - bottom, bw * 0.95, bottom=bottom, color=color)
    if text is not None:
        ax.bar_label(b, labels=[text], padding=2, fontsize=size)
    return b


def patch(color, label):
    return Patch(facecolor=color, label=label)


def stroke(color, label, style="-", width=1.5):
    return Line2D([], [], color=color, linestyle=style, linewidth=width, label=label)


def legend(ax, handles=None, title=None):
    """Legend to the right of the plot area."""
    kw = {"handles": handles} if handles is not None else {}
    ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1), frameon=False, fontsize=9, title=title,
              title_fontsize=9, alignment="left", **kw)


def save(fig, path):
    fig.savefig(path, format="svg", metadata={"Date": None})
    plt.close(fig)


def slug(path):
    base = os.path.basename(path)
    for ext in (".gltf", ".glb"):
        if base.endswith(ext):
            base = base[: -len(ext)]
    return "".join(c if c.isalnum() or c in "-_" else "-" for c in base)


def human(b, fmt="%.1f"):
    for unit, f in (("MiB", 2 ** 20), ("KiB", 2 ** 10)):
        if b >= f:
            return (fmt + " %s") % (b / f, unit)
    return "%d B" % b
