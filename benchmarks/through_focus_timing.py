"""Warm time of one through-focus call: 2x2, eleven eyes (seed 0 + the average eye), 9 depths,
0-5 D in 0.2 D steps within +-2 D, 10 nm, df 0.8409 cpd; grid only and with `local` peaks
(best of 2 after a first call). Written against the public API of every commit since
RESULTS 9, so that one sitting can time several commits, each from its own worktree:

    git worktree add /tmp/c COMMIT && (cd /tmp/c && PYTHONPATH=. python /path/to/this/script)
"""
import time, numpy as np, jax, lfjax
from lfjax.eyes import append_average_eye
eyes = append_average_eye(lfjax.sample_eyes(0, 10))
lay = lfjax.grid_layout(2, 3.0)
depths = np.round(2.0 + np.arange(-2, 2.01, 0.5), 9)
acc = np.round(np.arange(0, 5.001, 0.2), 9)
spec = lfjax.make_spectrum(np.arange(400, 700.1, 10.0))
s = lfjax.Sampling(0.8408964152537145)
def run(**kw):
    t = time.perf_counter()
    from lfjax.through_focus import through_focus as _tf
    tf = _tf(eyes, lay, depths, accommodation_D=acc, window_D=2.0, pupil_diameter_mm=3.0,
                             cdp_D=2.0, spectrum=spec, sampling=s, **kw)
    jax.block_until_ready(tf.vsotf); return time.perf_counter() - t
t0 = time.perf_counter(); a = run(); b = min(run() for _ in range(2))
c = run(continuous_peaks=("vsotf",), peak_method="local", refine_second_peaks=False)
d = min(run(continuous_peaks=("vsotf",), peak_method="local", refine_second_peaks=False) for _ in range(2))
print(f"grid: cold {a:.1f} warm {b:.2f} | local: cold {c:.1f} warm {d:.2f}")
