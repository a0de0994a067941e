"""One signal order (t, z, u, y): old positional calls keep their meaning for one release, with a warning."""

from __future__ import annotations

import numpy as np
import pytest

import nlobs

OSC = nlobs.System(states=["x1", "x2"], f=["x2", "-x1 + u"], inputs=["u"], outputs=["y"], h=["x1"])


def _ekf():
    return nlobs.design_ekf(OSC, Q=np.eye(2) * 1e-3, R=[[1e-2]], xhat0=[0.5, 0.0])


def test_step_takes_time_first_and_an_old_call_keeps_its_meaning():
    obs = nlobs.Observer(_ekf())
    z = obs.initial_state()
    new = obs.step(0.1, z, 0.01, [0.2], [0.3])
    with pytest.warns(DeprecationWarning, match=r"step\(z, t, dt, u, y\) is the old order; write step\(t, z, dt, u, y\)"):
        old = obs.step(z, 0.1, 0.01, [0.2], [0.3])
    np.testing.assert_array_equal(old, new)
    # time matters (the input is held, but t enters through nothing here): compare with an independent RK4 of x' only
    assert not np.allclose(obs.step(0.1, z, 0.5, [1.0], [0.3])[:2], z[:2])


def test_update_and_run_take_u_and_y_by_keyword():
    d = _ekf()
    t = np.linspace(0, 1, 11)
    u, y = np.sin(t)[:, None], np.cos(t)[:, None]
    comp = nlobs.Observer(d).compiled()
    new = comp.run(t, u=u, y=y, engine="vm").xhat
    with pytest.warns(DeprecationWarning, match=r"run\(t, u=\.\.\., y=\.\.\.\)"):
        old = comp.run(t, y, u, engine="vm").xhat
    np.testing.assert_array_equal(old, new)
    with pytest.raises(TypeError, match="give the signals by keyword"):
        comp.run(t, y, u=u, y=y)
    a, b = nlobs.Observer(d).start(), nlobs.Observer(d).start()
    for k in range(3):
        xa = a.update(t[k], u=u[k], y=y[k])
        with pytest.warns(DeprecationWarning, match=r"update\(t, y, u\) with positional signals is the old order"):
            xb = b.update(t[k], y[k], u[k])
        np.testing.assert_array_equal(xa, xb)
    # swapping u and y changes the estimate: the keywords are not ignored
    c = nlobs.Observer(d).start()
    assert not np.allclose([c.update(t[k], u=y[k], y=u[k]) for k in range(3)][-1], xa)
