"""Draw docs/figures/getting_started_through_focus.png: the curve of getting-started.md's
first example, from exactly that example's call.

    python docs/_tools/getting_started_figure.py

Takes a minute or two on two CPU cores (mostly compilation).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

import lfjax
from lfjax.vision.focus import through_focus
from lfjax.vision.peak_options import PeakOptions
from lfjax.vision.prepare import States
from lfjax.vision.viewing import Viewing

OUT = Path(__file__).resolve().parents[1] / "figures" / "getting_started_through_focus.png"


def main() -> None:
    eyes = lfjax.sample_eyes(0, 10, measured_pupil_mm=3.0)
    layout = lfjax.grid_layout(2, pupil_diameter_mm=3.0)
    depths = [0.0, 2.0, 4.0]
    tf = through_focus(
        eyes,
        layout,
        States.grid(np.round(np.arange(0, 5.01, 0.2), 9), depths_D=depths, window_D=1.0),
        Viewing(pupil_diameter_mm=3.0, cdp_D=2.0),
        options=lfjax.ModelOptions(),
        peaks=PeakOptions(metrics=("vsotf",)),
    )
    states = np.asarray(tf.accommodation_D)
    vsotf = np.asarray(tf.vsotf)
    allowed = np.asarray(tf.allowed)
    peaks = np.asarray(tf.continuous_accommodation_D("vsotf"))
    fig = Figure(figsize=(8.0, 2.8), layout="constrained")
    axes = fig.subplots(1, len(depths), sharey=True)
    for d, (ax, depth) in enumerate(zip(axes, depths)):
        keep = allowed[d]
        for e in range(vsotf.shape[0]):
            ax.plot(states[d][keep], vsotf[e, d, keep], color="0.6", lw=0.8)
        ax.plot(peaks[:, d], [vsotf[:, d, keep].max() * 1.04] * len(peaks), "|", color="C3",
                ms=8, label="continuous peaks")
        ax.axvline(depth, color="C0", lw=1, label="rendered depth")
        ax.axvline(2.0, color="C2", lw=1, ls="--", label="CDP")
        ax.set_title(f"2×2 views, point at {depth:g} D", fontsize=9)
        ax.set_xlabel("accommodation (D)")
    axes[0].set_ylabel("VSOTF")
    axes[-1].legend(fontsize=7, loc="lower right")
    OUT.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(OUT, dpi=110)
    print("wrote", OUT, "| grid peaks (D):", np.asarray(tf.predicted_accommodation_D()).mean(0))


if __name__ == "__main__":
    main()
