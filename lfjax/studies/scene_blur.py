"""The blur of the rest of the scene over layouts, panels, depths and a population.

The authors' open question: with the CDP at 2 D and the eye focused on a point rendered at
4 D, what does a point rendered at 0 D look like — is its blur the blur of natural viewing?
:func:`run_scene_blur` answers it for every eye of a population: each eye's predicted
accommodation for the fixated depth through each display (the continuous VSOTF peak in the
display's white), then the blur of points at the other depths through the display and in
natural viewing at that same accommodation, per primary
(:func:`lfjax.vision.scene_blur.rest_of_scene`). :func:`scene_blur_table` gives population
medians and 5–95 % bands; :func:`save_scene_blur_figures` draws them.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from lfjax.display.panel import PRESETS, Panel
from lfjax.model.eyes import Eyes
from lfjax.model.layouts import grid_layout
from lfjax.model.options import ModelOptions
from lfjax.vision.focus import through_focus
from lfjax.display.spectra import display_spectrum
from lfjax.vision.scene_blur import rest_of_scene
from lfjax.vision.peak_options import PeakOptions
from lfjax.vision.prepare import States
from lfjax.vision.viewing import Viewing

DISPLAYS = ("natural", "2x2", "3x3", "4x4", "phone", "near-eye")
"""The paper's layouts (CDP ``cdp_D``) and the panel presets (their own CDP, lenslet
diffraction and pixels)."""

MEASURES = ("equivalent_defocus_D", "natural_equivalent_defocus_D", "match_rms", "mtf_ratio",
            "mtf_rms", "cue_display", "cue_natural")


@dataclass(frozen=True)
class SceneBlurConfig:
    """What :func:`run_scene_blur` computes.

    fixation_D : the fixated rendered depth, D (the authors' 4 D)
    depths_D : the other points of the scene, D
    displays : names from :data:`DISPLAYS`
    primaries : the display's primaries (built-in name)
    cdp_D : CDP of the paper's layouts, D (the panels keep their own)
    pupil_diameter_mm : calculation pupil, mm
    grid_step_D : step of the natural-defocus search of the equivalent defocus, D
    grid_margin_D : the search spans the true defocus ± this, D
    accommodation_offsets_D : accommodation states searched for the predicted accommodation,
        relative to the fixated depth, D (−3 … +1 D in 0.2 D: from past a 2 D CDP to beyond)
    """

    fixation_D: float = 4.0
    depths_D: tuple = (0.0, 0.5, 1.0, 2.0, 3.0, 4.0, 5.0)
    displays: tuple = DISPLAYS
    primaries: str = "oled"
    cdp_D: float = 2.0
    pupil_diameter_mm: float = 3.0
    grid_step_D: float = 0.1
    grid_margin_D: float = 1.5
    accommodation_offsets_D: tuple = tuple(np.round(np.arange(-3.0, 1.0 + 1e-9, 0.2), 6))

    def __post_init__(self):
        bad = [d for d in self.displays if d not in DISPLAYS]
        if bad:
            raise ValueError(f"displays must be among {DISPLAYS}, got {bad}")

    def display(self, name: str):
        """(layout or None, DisplayOptics or None, cdp_D, label) of a display name."""
        if name == "natural":
            return None, None, self.cdp_D, "natural"
        if name in ("2x2", "3x3", "4x4"):
            return grid_layout(int(name[0]), self.pupil_diameter_mm), None, self.cdp_D, name
        panel: Panel = PRESETS[name](pupil_diameter_mm=self.pupil_diameter_mm)
        n = panel.n_views_per_side()
        return panel.layout(), panel.optics(), float(panel.cdp_D), f"{name} ({n}x{n})"


def run_scene_blur(eyes: Eyes, config: SceneBlurConfig = SceneBlurConfig(),
                   options: ModelOptions = ModelOptions(), progress: bool = True) -> dict:
    """Every measure for displays × eyes × depths: a dict of arrays (n_display, n_eye, n_depth)
    (:data:`MEASURES`, ``true_defocus_D``), ``accommodation_D`` (n_display, n_eye), the labels,
    CDPs and the configuration."""
    depths = np.asarray(config.depths_D, float)
    white = display_spectrum(config.primaries, "white", options)
    out = {k: np.full((len(config.displays), eyes.n_eyes, depths.size), np.nan)
           for k in MEASURES + ("true_defocus_D",)}
    acc = np.full((len(config.displays), eyes.n_eyes), np.nan)
    labels, cdps = [], []
    t0 = time.perf_counter()
    for i, name in enumerate(config.displays):
        layout, optics, cdp, label = config.display(name)
        labels.append(label)
        cdps.append(cdp)
        # natural viewing: a real point at the fixated depth (the open pupil shows its point
        # at its CDP, whatever depth it is given)
        # The search reaches from the fixated depth down past the CDP: a display whose views
        # drive accommodation weakly (lenslet diffraction) leaves the eye near its CDP.
        tf = through_focus(
            eyes,
            layout,
            States.grid(None, depths_D=[config.fixation_D]),
            Viewing(
                pupil_diameter_mm=config.pupil_diameter_mm,
                cdp_D=config.fixation_D if layout is None else cdp,
                display=optics,
            ),
            spectrum=white,
            options=options,
            peaks=PeakOptions(metrics=("vsotf",)),
        )
        a = np.asarray(tf.continuous_accommodation_D()[:, 0], float)
        grid_a = np.asarray(tf.predicted_accommodation_D()[:, 0], float)
        acc[i] = np.where(np.isfinite(a), a, grid_a)
        for e in range(eyes.n_eyes):
            true = depths - acc[i, e]
            grid = np.round(np.arange(true.min() - config.grid_margin_D,
                                      true.max() + config.grid_margin_D + 1e-9,
                                      config.grid_step_D), 6)
            r = rest_of_scene(eyes[e:e + 1], layout, acc[i, e], depths, config.primaries,
                              pupil_diameter_mm=config.pupil_diameter_mm, cdp_D=cdp,
                              options=options, display=optics, grid_defocus_D=grid)
            for k in MEASURES + ("true_defocus_D",):
                out[k][i, e] = r[k]
            if progress:
                print(f"  {label}: eye {e + 1}/{eyes.n_eyes}, a = {acc[i, e]:.3f} D "
                      f"({time.perf_counter() - t0:.0f} s)", flush=True)
    out.update(accommodation_D=acc, labels=labels, cdp_D=np.asarray(cdps), depths_D=depths,
               config=asdict(config), seconds=time.perf_counter() - t0)
    return out


def _band(x, axis=0):
    return (np.nanmedian(x, axis=axis), np.nanpercentile(x, 5, axis=axis),
            np.nanpercentile(x, 95, axis=axis))


def cue_agreement(result: dict) -> np.ndarray:
    """Fraction of eyes whose display cue has the natural cue's sign, (n_display, n_depth)."""
    same = np.sign(result["cue_display"]) == np.sign(result["cue_natural"])
    return np.mean(same, axis=1)


def scene_blur_table(result: dict) -> str:
    """Markdown: per display and depth, the true and equivalent defocus, the MTF ratio and
    RMS, and the colour cue (population medians [5 %, 95 %])."""
    rows = ["| display | depth (D) | true defocus d − a (D) | equivalent defocus (D) | "
            "NCSF-weighted MTF ratio display/natural | MTF RMS difference | "
            "cue natural | cue display | cue sign kept |",
            "| --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    agree = cue_agreement(result)
    for i, label in enumerate(result["labels"]):
        for j, d in enumerate(result["depths_D"]):
            cells = []
            for k, fmt in (("true_defocus_D", "{:+.2f}"), ("equivalent_defocus_D", "{:+.2f}"),
                           ("mtf_ratio", "{:.2f}"), ("mtf_rms", "{:.3f}"),
                           ("cue_natural", "{:+.2f}"), ("cue_display", "{:+.2f}")):
                m, lo, hi = _band(result[k][i, :, j])
                cells.append(fmt.format(m) + (f" [{fmt.format(lo)}, {fmt.format(hi)}]"
                                              if result[k].shape[1] > 1 else ""))
            rows.append(f"| {label} | {d:g} | " + " | ".join(cells) + f" | {agree[i, j]:.0%} |")
    return "\n".join(rows)


def save_scene_blur_figures(result: dict, out) -> list[str]:
    """Two figures: the equivalent defocus and MTF ratio against the true defocus, and the
    colour cue display against natural; returns their paths."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    n_eyes = result["accommodation_D"].shape[1]
    colours = plt.cm.viridis(np.linspace(0, 0.9, len(result["labels"])))
    fig, ax = plt.subplots(1, 2, figsize=(11, 4.4))
    for i, label in enumerate(result["labels"]):
        true = np.nanmedian(result["true_defocus_D"][i], axis=0)
        for k, a in ((("equivalent_defocus_D"), ax[0]), ("mtf_ratio", ax[1])):
            m, lo, hi = _band(result[k][i])
            a.plot(true, m, "o-", color=colours[i], label=label, ms=4)
            if n_eyes > 1:
                a.fill_between(true, lo, hi, color=colours[i], alpha=0.15)
    lim = np.nanmax(np.abs(result["true_defocus_D"])) + 0.3
    ax[0].plot([-lim, lim], [-lim, lim], "k:", lw=1, label="natural (d − a)")
    ax[0].set(xlabel="true defocus d − a (D; > 0 nearer than focus)",
              ylabel="equivalent natural defocus (D)",
              title="Blur of the rest of the scene: equivalent defocus")
    ax[1].axhline(1.0, color="k", ls=":", lw=1)
    ax[1].set(xlabel="true defocus d − a (D)", ylabel="Σ NCSF·MTF display / natural",
              yscale="log", title="How much sharper than nature (1: as natural)")
    ax[0].legend(fontsize=8)
    fig.suptitle(f"fixated {result['config']['fixation_D']:g} D, {n_eyes} eye(s), "
                 f"{result['config']['primaries']} primaries; median and 5–95 %", fontsize=9)
    fig.tight_layout()
    p1 = out / "scene_blur_equivalent_defocus.png"
    fig.savefig(p1, dpi=110)
    plt.close(fig)

    fig, ax = plt.subplots(1, 2, figsize=(11, 4.2))
    agree = cue_agreement(result)
    for i, label in enumerate(result["labels"]):
        true = np.nanmedian(result["true_defocus_D"][i], axis=0)
        m, lo, hi = _band(result["cue_display"][i])
        ax[0].plot(true, m, "o-", color=colours[i], label=label, ms=4)
        ax[1].plot(true, agree[i], "o-", color=colours[i], label=label, ms=4)
    m, _, _ = _band(result["cue_natural"][0])
    ax[0].plot(np.nanmedian(result["true_defocus_D"][0], axis=0), m, "k--", lw=2,
               label="natural viewing")
    ax[0].axhline(0, color="k", lw=0.5)
    ax[0].set(xlabel="true defocus d − a (D; > 0 nearer)",
              ylabel="(m_R − m_B)/(m_R + m_B)",
              title="Colour cue: > 0 red sharper (farther), < 0 blue sharper (nearer)")
    ax[1].set(xlabel="true defocus d − a (D)", ylabel="eyes whose cue keeps the natural sign",
              ylim=(-0.05, 1.05), title="Does the display keep the cue's sign?")
    ax[0].legend(fontsize=8)
    fig.tight_layout()
    p2 = out / "scene_blur_colour_cue.png"
    fig.savefig(p2, dpi=110)
    plt.close(fig)
    return [str(p1), str(p2)]


__all__ = ["DISPLAYS", "MEASURES", "SceneBlurConfig", "run_scene_blur", "scene_blur_table",
           "cue_agreement", "save_scene_blur_figures"]
