"""Retinal images of a scene are differentiable in the display's parameters: the gradient of a
loss on the composited retinal image of a two-layer scene (the average eye, a 3×3 layout,
laser primaries) with respect to a scale of the views' diameters, against a central finite
difference. Too slow for the suite (a minute of compiling on 2 cores), so run here:

    python benchmarks/validation/scene_gradients.py
"""
import time, numpy as np, jax, jax.numpy as jnp, equinox as eqx
from lfjax.base.sampling import Sampling
from lfjax.model.eyes import average_eye
from lfjax.model.layouts import grid_layout
from lfjax.vision import scene_images as si
from lfjax.vision.scene_blur import channel_spectra, display_otfs, embed_otf
eye = average_eye(3.0)
spectra = channel_spectra("laser")
sampling = Sampling(freq_step_cpd=2.0, n_fft=128)
rng = np.random.default_rng(0)
layers = jnp.asarray(rng.random((2, 3, 16, 16)), jnp.float32)
alpha = jnp.ones((2, 16, 16), jnp.float32).at[0, :, :8].set(0.0)
layers = layers * alpha[:, None]
base = grid_layout(3)
def loss(scale):
    lay = eqx.tree_at(lambda l: l.diameters_mm, base, base.diameters_mm * scale)
    otf = display_otfs(eye, lay, 2.2, [3.0, 1.0], spectra, sampling, cdp_D=2.0)
    otf = embed_otf(otf, 128)
    return jnp.sum(si.composite_layers(layers, alpha, otf, 2.0, 0.5) ** 2)
t=time.time()
g = jax.grad(loss)(0.9)
h = 1e-3
fd = (loss(0.9 + h) - loss(0.9 - h)) / (2 * h)
print("d loss / d (view diameter scale): grad", float(g), "finite difference", float(fd), time.time()-t)
