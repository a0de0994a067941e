"""The starts of the likelihood fit: a start that converges at the recursion's integration and then loses convergence
when polished at the finer integration its estimate needs is a start that did not converge, and the next start is
tried (before: the fit stopped there, reported NOT converged, and never tried the simulation-error start)."""

from __future__ import annotations

import numpy as np

import nlobs
from nlobs.learning import fit_likelihood
from nlobs.estimation import Recording
from nlobs.learning import _fit_likelihood as F
from nlobs.learning._likelihood import _Problem


def _decay():
    system = nlobs.System(states=["x"], f=["-k*x + u"], inputs=["u"], outputs=["y"], h=["x"], params={"k": 0.3})
    t = np.arange(0.0, 40.0, 0.5)
    u = np.sign(np.sin(0.4 * t))
    truth = nlobs.simulate(system.with_params(k=0.5), {}, t_final=40.0, dt=0.01, x0=[1.0],
                           inputs={"u": (t, u)})
    y = np.interp(t, truth.t, truth.x[:, 0]) + np.random.default_rng(3).normal(0, 0.02, t.size)
    rec = Recording(t=t, u=u[:, None], y=y[:, None], input_names=("u",), output_names=("y",))
    return nlobs.design_ekf(system, Q=[[1e-4]], R=[[4e-4]], xhat0=[1.0], P0=[[0.1]]), rec


def test_a_start_lost_when_integrated_finer_is_followed_by_the_next_start(monkeypatch):
    design, rec = _decay()
    asked: list[int] = []

    def needed(self, theta):   # the first converged estimate asks for one more sub-step, later ones for none
        asked.append(self.n_sub)
        return self.n_sub + 1 if len(asked) == 1 else self.n_sub

    real = F._optimise

    def optimise(obj, phi0, start, max_iter):
        att = real(obj, phi0, start, max_iter)
        if start.startswith("initial guess, integrated with"):   # the polish of the first start does not converge
            att.converged, att.message = False, "forced: not converged at the finer integration"
        return att

    monkeypatch.setattr(_Problem, "needed_substeps", needed)
    monkeypatch.setattr(F, "_optimise", optimise)
    fit = fit_likelihood(design, rec, ["k"], learn_noise=True)
    starts = [(a["start"], a["converged"]) for a in fit.attempts]
    assert starts[0] == (starts[0][0], False) and starts[0][0].startswith("initial guess, integrated with"), starts
    assert starts[-1] == ("simulation-error fit", True), starts
    assert fit.success and np.all(np.isfinite(fit.std))
    assert abs(fit.parameters["k"]["estimate"] - 0.5) <= 3 * fit.parameters["k"]["std"]


def test_a_start_that_puts_a_positive_unknown_below_zero_is_moved_back_inside():
    # a simulation-error start knows no sign: k5 = -24 for a parameter scaled by its logarithm gave log(-24) = NaN
    import numpy as np

    from nlobs.learning._fit_likelihood import _Scaling

    sc = _Scaling(["a", "k5"], np.array([0.02, 1.4]), np.array([-np.inf, -np.inf]), np.array([np.inf, np.inf]), set())
    th = sc.admissible(np.array([0.05, -23.98]), np.array([0.02, 1.4]))
    assert np.all(np.isfinite(sc.phi(th))) and th[0] == 0.05 and 0 < th[1] < 1.4


def test_the_command_lines_iteration_budget_is_the_librarys():
    # the CLI cannot import the learning layer when it starts (SciPy, CasADi); its help names the same default
    from nlobs.cli import _parser
    from nlobs.learning._fit_likelihood import MAX_ITER

    fit = next(a for a in _parser()._subparsers._group_actions[0].choices["fit"]._actions if a.dest == "max_iter")
    assert fit.default is None and f"default {MAX_ITER}," in fit.help
