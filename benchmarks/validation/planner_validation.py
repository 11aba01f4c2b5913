"""Planner validation: plan, measured error, and one step cheaper, on five small scenes.

For each scene (aberration-free eye, 450/550/650 nm, accommodation 0–4 D in 0.2 D steps
within a window of each rendered depth) the planner's sampling and each rejected cheaper
neighbour are run through lfjax.vision.focus; the measured error is max |VSOTF − converged|
where converged is Richardson-extrapolated from a quarter and an eighth of the plan's step; "wrap" is
the pipeline's wrapped PSF / peak on the plan's field. tests/planner/test_plan.py asserts the
parts that hold; benchmarks/RESULTS.md §7 records a run.

Run:  .venv/bin/python benchmarks/validation/planner_validation.py [tolerance, default 2e-3]
"""
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(1, str(Path(__file__).resolve().parents[1]))  # benchmarks/: _common

from _common import header  # noqa: E402

import lfjax
from lfjax.planner import PlanScene, Targets, plan_sampling
from lfjax.vision.focus import through_focus
from lfjax.kernel.optics import psf_from_otf
from lfjax.vision.psf import polychromatic_otf
from lfjax.vision.prepare import States
from lfjax.vision.viewing import Viewing

WL=[450.,550.,650.]
sp=lfjax.make_spectrum(WL)

def vs(eye, lay, depths, acc, win, s, pupil):
    tf = through_focus(
        eye,
        lay,
        States.grid(acc, depths_D=depths, window_D=win),
        Viewing(pupil_diameter_mm=pupil),
        spectrum=sp,
        sampling=s,
        check_aliasing=False,
    )
    return np.asarray(tf.vsotf), np.asarray(tf.allowed)

def wrap(eye, lay, depths, acc, win, df, pupil):
    worst=0
    for d in depths:
        a=[x for x in acc if abs(x-d)<=win+1e-9]
        o = polychromatic_otf(
            eye,
            a,
            Viewing(pupil_diameter_mm=pupil, cdp_D=2.0),
            layout=lay,
            depths_D=[d],
            spectrum=sp,
            sampling=lfjax.Sampling(df / 2),
            check_aliasing=False,
        )
        P=np.asarray(psf_from_otf(o.otf, o.n_fft, df/2))[0,0]
        L=P.shape[-1]; h=L//2
        F=P+np.roll(P,h,-1)+np.roll(P,h,-2)+np.roll(np.roll(P,h,-1),h,-2)
        c=slice(L//2-h//2, L//2-h//2+h)
        worst=max(worst, float(((F-P)[:,c,c].max(axis=(-2,-1))/P.max(axis=(-2,-1))).max()))
    return worst

scenes = {
 "open": (lfjax.open_pupil(3.0), [2.0], 3.0, 1.0),
 "2x2": (lfjax.grid_layout(2,3.0), [1.0,2.0,3.0], 3.0, 1.0),
 "4x4": (lfjax.grid_layout(4,3.0), [1.5,2.5], 3.0, 0.6),
 "4x4 wide": (lfjax.grid_layout(4,3.0), [1.0,2.0,3.0], 3.0, 1.0),
 "3x3-4mm": (lfjax.grid_layout(3,4.0), [1.0,3.0], 4.0, 0.6),
}
tol=float(sys.argv[1]) if len(sys.argv)>1 else 2e-3
header(f"planner_validation: plans for VSOTF error <= {tol:g} against the pipeline (issue #5)")
for name,(lay,depths,pupil,win) in scenes.items():
    eye = lfjax.model.eyes.aberration_free_eye(measured_pupil_mm=max(pupil,3.0))
    acc=np.round(np.arange(0,4.01,0.2),9)
    t=time.time()
    plan=plan_sampling(PlanScene(lay, pupil, 2.0, depths_D=depths, accommodation_D=acc, accommodation_window_D=win, wavelengths_nm=WL), Targets(vsotf=tol))
    tp=time.time()-t
    s=plan.sampling
    # one converged reference for the plan and its neighbours: Richardson (order 2) from
    # a quarter and an eighth of the plan's step
    r8,allowed=vs(eye,lay,depths,acc,win,lfjax.Sampling(s.freq_step_cpd/8),pupil)
    r4,_=vs(eye,lay,depths,acc,win,lfjax.Sampling(s.freq_step_cpd/4),pupil)
    ref = r8 + (r8-r4)/3
    # the cheaper reference the tests use: Richardson from a half and a quarter of the step
    r2,_=vs(eye,lay,depths,acc,win,lfjax.Sampling(s.freq_step_cpd/2),pupil)
    mask=np.broadcast_to(allowed[None], r2.shape)
    print(f"   reference check: max |R(df/2, df/4) - R(df/4, df/8)| = "
          f"{np.abs(r4 + (r4-r2)/3 - ref)[mask].max():.1e}", flush=True)
    v,_=vs(eye,lay,depths,acc,win,s,pupil)
    m=allowed[None]
    e=np.abs(v-ref)[np.broadcast_to(m,v.shape)].max()
    w=wrap(eye,lay,depths,acc,win,s.freq_step_cpd,pupil)
    print(f"== {name}: plan {s.transform} df {s.freq_step_cpd:.4g} N {s.mft_pupil_samples} ({tp:.1f}s) est {plan.errors['pupil']:.2e}/{plan.errors['psf_wrap']:.2e} measured vsotf {e:.2e} wrap {w:.2e}", flush=True)
    for dim,(sc,why) in plan.cheaper.items():
        v,_=vs(eye,lay,depths,acc,win,sc,pupil)
        e=np.abs(v-ref)[np.broadcast_to(m,v.shape)].max()
        w=wrap(eye,lay,depths,acc,win,sc.freq_step_cpd,pupil)
        print(f"   cheaper {dim}: {why} | measured vsotf {e:.2e} wrap {w:.2e}", flush=True)
