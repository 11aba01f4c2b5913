"""Exported programs kept across processes (lfjax.base.programs).

A later process is stood in for by forgetting the loaded programs (``clear_loaded``): the
program must then come from its file, not from tracing the function again, and give the
same numbers as calling the function directly.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from lfjax.base import programs

TRACES = []


def affine(params, x, *, power):
    """A pure function of a pytree of arrays and a static choice (counts its tracings)."""
    TRACES.append(power)
    return {"y": params["a"] * x ** power + params["b"], "sum": jnp.sum(x)}


def with_callback(x, *, scale):
    jax.debug.callback(lambda v: None, x)  # host callbacks cannot be exported
    return x * scale


@pytest.fixture
def cache(tmp_path):
    folder = programs.enable_program_cache(tmp_path / "programs")
    programs.clear_loaded()
    TRACES.clear()
    yield folder
    programs.enable_program_cache(None)
    programs.clear_loaded()


def _args():
    params = {"a": jnp.asarray(2.0), "b": np.array([1.0, -1.0, 0.5], np.float32)}
    return params, jnp.linspace(0.0, 1.0, 3)


def test_exported_once_then_loaded_without_tracing(cache):
    params, x = _args()
    expected = affine(params, x, power=3)
    first = programs.call_cached(affine, params, x, power=3)
    files = list(cache.glob("*.jaxexport"))
    assert len(files) == 1
    programs.clear_loaded()  # a new process
    TRACES.clear()
    again = programs.call_cached(affine, params, x, power=3)
    assert TRACES == []  # loaded from the file, not traced
    for got in (first, again):
        assert set(got) == {"y", "sum"}
        np.testing.assert_allclose(got["y"], expected["y"], rtol=1e-6)
        np.testing.assert_allclose(got["sum"], expected["sum"], rtol=1e-6)
    # new values, same shapes: the same program; another static choice: another program
    other = programs.call_cached(affine, {"a": jnp.asarray(-1.0), "b": params["b"]}, x, power=3)
    np.testing.assert_allclose(other["y"], -x ** 3 + params["b"], rtol=1e-6)
    programs.call_cached(affine, params, x, power=2)
    programs.call_cached(affine, {"a": params["a"], "b": np.ones(5, np.float32)}, jnp.ones(5),
                         power=3)
    assert len(list(cache.glob("*.jaxexport"))) == 3


def test_damaged_entry_is_exported_again(cache):
    params, x = _args()
    programs.call_cached(affine, params, x, power=3)
    (path,) = cache.glob("*.jaxexport")
    path.write_bytes(path.read_bytes()[:40])
    programs.clear_loaded()
    got = programs.call_cached(affine, params, x, power=3)
    np.testing.assert_allclose(got["y"], affine(params, x, power=3)["y"], rtol=1e-6)
    assert path.stat().st_size > 40  # rewritten whole


def test_direct_call_when_off_traced_or_not_exportable(cache):
    params, x = _args()
    # traced arguments: the function itself, inside the caller's transformation
    grad = jax.grad(lambda a: programs.call_cached(affine, {"a": a, "b": params["b"]}, x,
                                                   power=2)["y"].sum())(jnp.asarray(2.0))
    np.testing.assert_allclose(grad, np.sum(np.asarray(x) ** 2), rtol=1e-6)
    # a host callback cannot be exported: run as it is, nothing written
    np.testing.assert_allclose(programs.call_cached(with_callback, x, scale=2.0), 2 * x)
    assert list(cache.glob("*.jaxexport")) == []
    programs.enable_program_cache(None)
    np.testing.assert_allclose(programs.call_cached(affine, params, x, power=1)["y"],
                               2.0 * x + params["b"], rtol=1e-6)
    assert list(cache.glob("*.jaxexport")) == []


def test_a_worker_thread_computes_under_the_callers_dtype_setting():
    """``jax.enable_x64`` as a context holds for its own thread only: a plain worker thread
    computes in the session's dtype, the wrapped function in the caller's."""
    import threading

    import jax
    import jax.numpy as jnp

    from lfjax.base.programs import in_callers_jax_context

    def dtype():
        return jnp.asarray(1.0).dtype

    for x64 in (False, True):
        seen = {}
        with jax.enable_x64(x64):
            wrapped = in_callers_jax_context(dtype)
            plain = threading.Thread(target=lambda: seen.update(plain=dtype()))
            inner = threading.Thread(target=lambda: seen.update(wrapped=wrapped()))
            for thread in (plain, inner):
                thread.start()
                thread.join()
        assert seen["wrapped"] == (jnp.float64 if x64 else jnp.float32)
        assert seen["plain"] == (jnp.float64 if jax.config.jax_enable_x64 else jnp.float32)
