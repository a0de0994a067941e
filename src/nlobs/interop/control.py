"""python-control in and out: plants from ``control.StateSpace`` / ``control.NonlinearIOSystem``,
observers as ``control.NonlinearIOSystem``.

python-control is optional (``pip install 'nlobs[interop]'``) and imported only when one of
these functions is called, so ``import nlobs`` never imports it.

Conventions follow python-control's own estimator, ``control.create_estimator_iosystem``: the
observer's inputs are the plant's measured outputs followed by its inputs, ``[y..., u...]``
(named like the plant's signals, so :func:`control.interconnect` connects them by name), and
its outputs are the estimates ``xhat[0], xhat[1], ...``.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from typing import Any

import numpy as np

from ..design import check_positive
from ..engine import compile_system
from ..errors import ModelError, PreconditionError, ShapeError
from ..model import LTI, System
from ..observer import AbstractObserver, as_observer

__all__ = ["from_control", "to_control"]

_DEFAULT_LABEL = re.compile(r"^[xuy]\[\d+\]$")


def _control() -> Any:
    try:
        import control  # noqa: PLC0415 - optional dependency, imported on use only
    except ImportError as e:  # pragma: no cover - the test extra installs it
        raise ImportError("python-control is not installed; install it with: pip install 'nlobs[interop]' "
                          "(or pip install control)") from e
    return control


def _sanitise(label: str) -> str:
    """A python-control signal label as an nlobs name: ``x[0]`` -> ``x0``, other characters -> ``_``."""
    name = re.sub(r"\[(\d+)\]", r"\1", str(label))
    name = re.sub(r"[^A-Za-z0-9_]", "_", name).strip("_")
    return name if name[:1].isalpha() else f"s_{name}"


def _names(given: Sequence[str] | None, labels: Sequence[str], kind: str, sysname: str) -> list[str]:
    if given is not None:
        if isinstance(given, str) or len(given) != len(labels):
            raise ShapeError(f"from_control: `{kind}` must be a list of {len(labels)} name(s) for the system {sysname!r}, "
                             f"got {given!r}")
        return list(given)
    names = [_sanitise(lb) for lb in labels]
    if len(set(names)) != len(names):
        raise ModelError(f"from_control: the {kind} labels {list(labels)} of {sysname!r} collide once made into names "
                         f"({names}); pass `{kind}=[...]` with distinct names")
    return names


def _sample_time(sys: Any, caller: str) -> float | None:
    """None for a continuous-time python-control system; its sample period for a discrete-time one."""
    dt = getattr(sys, "dt", 0)
    if dt is None or dt is False or dt == 0:
        return None
    if dt is True:
        raise PreconditionError(f"{caller}: the python-control system {sys.name!r} is discrete-time with an unspecified "
                                "sample period (dt = True); give it one (e.g. control.ss(A, B, C, D, 0.1)): nlobs maps have "
                                "a sample time in seconds")
    return float(dt)


def from_control(sys: Any, *, twin: System | None = None, name: str | None = None,
                 states: Sequence[str] | None = None, inputs: Sequence[str] | None = None,
                 outputs: Sequence[str] | None = None, points: Sequence[tuple[Any, Any, Any]] | None = None,
                 n_points: int = 16, seed: int = 0, rtol: float = 1e-8) -> System:
    r"""An nlobs plant from a python-control system.

    - A ``control.StateSpace`` (continuous-time) becomes the LTI model
      :math:`\dot x = Ax + Bu,\ y = Cx + Du` (exactly, through :class:`nlobs.model.LTI`); a discrete-time one
      (``dt = T``) the map :math:`x[k+1] = Ax[k] + Bu[k]` with ``sample_time = T``.
      Signal labels become names: ``x[0]`` becomes ``x0``; other characters become ``_``.
    - A ``control.NonlinearIOSystem`` holds opaque Python functions, while nlobs needs f and h
      symbolically (Lie derivatives, Jacobians, C code). Pass its symbolic `twin`, an
      :class:`nlobs.System` with the same equations: the twin is returned after a numerical
      check that its f and h equal the system's ``updfcn`` and ``outfcn`` (evaluated through
      ``sys.dynamics`` / ``sys.output`` with the system's own parameters) at sample points,
      to within ``|a - b| <= rtol (1 + max(|a|, |b|))``.

    Parameters
    ----------
    sys : control.StateSpace or control.NonlinearIOSystem
        The plant, continuous-time (``dt = 0``) or discrete-time (``dt = T``; a twin must then be a map with
        ``sample_time = T``).
    twin : System, optional
        The symbolic model of a ``NonlinearIOSystem`` (required for one; optional for a
        ``StateSpace``, which is then checked against it the same way).
    name : str, optional
        The model's name (default: the python-control system's name).
    states, inputs, outputs : sequence of str, optional
        Names for a ``StateSpace`` without a twin (default: its labels, sanitised).
    points : sequence of (t, x, u), optional
        Where to compare the twin with the python-control functions (default: `n_points`
        seeded random points, t in [0, 10], x and u standard normal). Give points inside the
        functions' domain when they are not defined everywhere.
    n_points : int
        Number of random comparison points when `points` is not given.
    seed : int
        Seed of the random comparison points.
    rtol : float
        Relative tolerance of the comparison.

    Returns
    -------
    System

    Raises
    ------
    TypeError
        For a transfer function (convert it with ``control.ss`` first) or another object.
    PreconditionError
        For a discrete-time system without a sample period (``dt = True``), or a ``NonlinearIOSystem`` without
        a twin.
    ModelError
        When the twin's sizes, signal names or equations differ from the python-control
        system's (naming the equation, the point and both values), or labels collide.

    Examples
    --------
    >>> import control as ct
    >>> plant = ct.ss([[0, 1], [-2, -3]], [[0], [1]], [[1, 0]], 0, states=["p", "v"], inputs=["F"], outputs=["pos"])
    >>> from_control(plant, name="cart").states
    ('p', 'v')
    """
    ct = _control()
    caller = "from_control"
    if isinstance(sys, ct.TransferFunction):
        raise TypeError(f"{caller}: got a transfer function; nlobs needs a state-space model: convert it with "
                        "control.ss(sys) (the states then are that realisation's)")
    if not isinstance(sys, ct.NonlinearIOSystem):
        raise TypeError(f"{caller}: expected a control.StateSpace or control.NonlinearIOSystem, got {type(sys).__name__}")
    T = _sample_time(sys, caller)
    label = name or sys.name
    if twin is None:
        if not isinstance(sys, ct.StateSpace):
            raise PreconditionError(
                f"{caller}: {sys.name!r} is a NonlinearIOSystem, whose updfcn/outfcn are opaque Python functions; nlobs "
                "needs the equations symbolically. Pass twin=nlobs.System(...) with the same f and h (it is checked "
                "numerically against updfcn and outfcn)")
        A, B, C, D = (np.asarray(M, dtype=float) for M in (sys.A, sys.B, sys.C, sys.D))
        n, m, p = sys.nstates, sys.ninputs, sys.noutputs
        lti = LTI(A, B.reshape(n, m), C.reshape(p, n), D.reshape(p, m),
                  states=_names(states, sys.state_labels, "states", sys.name),
                  inputs=_names(inputs, sys.input_labels, "inputs", sys.name),
                  outputs=_names(outputs, sys.output_labels, "outputs", sys.name), name=label).to_system()
        if T is None:
            return lti
        # x[k+1] = A x[k] + B u[k]: the same matrices as a map with python-control's sample period
        return System(states=list(lti.states), inputs=list(lti.inputs), outputs=list(lti.outputs), f=list(lti.f),
                      h=list(lti.h), params=dict(lti.params), name=label, time="discrete", sample_time=T)
    if not isinstance(twin, System):
        raise TypeError(f"{caller}: `twin` must be an nlobs.System, got {type(twin).__name__}")
    if (T is None) != (not twin.is_discrete) or (T is not None and abs(T - twin.sample_time) > 1e-12 * T):
        theirs = "continuous-time" if T is None else f"discrete-time with dt = {T:g}"
        mine = f"discrete-time with sample_time = {twin.sample_time:g}" if twin.is_discrete else "continuous-time"
        raise ModelError(f"{caller}: {sys.name!r} is {theirs} but the twin {twin.name!r} is {mine}; give the twin the same "
                         "time base (System(..., time='discrete', sample_time=dt) for a map)")
    if states is not None or inputs is not None or outputs is not None:
        raise ModelError(f"{caller}: with a twin the names are the twin's; rename in the twin instead of passing "
                         "states/inputs/outputs")
    _check_twin(sys, twin, points, n_points, seed, rtol)
    return twin if name is None else twin.with_name(name)


def _check_twin(sys: Any, twin: System, points: Any, n_points: int, seed: int, rtol: float) -> None:
    caller = "from_control"
    for kind, mine, theirs, labels in (("states", twin.states, sys.nstates, sys.state_labels),
                                       ("inputs", twin.inputs, sys.ninputs, sys.input_labels),
                                       ("outputs", twin.outputs, sys.noutputs, sys.output_labels)):
        if len(mine) != theirs:
            raise ModelError(f"{caller}: the twin {twin.name!r} has {len(mine)} {kind} {list(mine)}, the python-control "
                             f"system {sys.name!r} has {theirs} ({list(labels)}); they must describe the same plant")
        custom = [lb for lb in labels if not _DEFAULT_LABEL.match(lb)]
        if custom:  # labels chosen by the user: they must name the same signals, in the same order
            for i, (a, b) in enumerate(zip(mine, labels)):
                if _sanitise(b) != a:
                    raise ModelError(f"{caller}: {kind[:-1]} {i} is {a!r} in the twin but {b!r} in {sys.name!r}; "
                                     f"order and name the {kind} alike (twin: {list(mine)}, python-control: {list(labels)})")
    if not (isinstance(rtol, (int, float)) and rtol > 0):
        raise ValueError(f"{caller}: `rtol` must be a positive number, got {rtol!r}")
    n, m = twin.n_states, twin.n_inputs
    if points is None:
        if int(n_points) < 1:
            raise ValueError(f"{caller}: `n_points` must be at least 1, got {n_points!r}")
        rng = np.random.default_rng(seed)
        pts = [(rng.uniform(0, 10), rng.standard_normal(n), rng.standard_normal(m)) for _ in range(int(n_points))]
    else:
        pts = []
        for k, pt in enumerate(points):
            try:
                t, x, u = pt
            except (TypeError, ValueError):
                raise ShapeError(f"{caller}: `points[{k}]` must be a tuple (t, x, u), got {pt!r}") from None
            x_, u_ = np.asarray(x, dtype=float).reshape(-1), np.asarray(u if u is not None else [], dtype=float).reshape(-1)
            if x_.size != n or u_.size != m:
                raise ShapeError(f"{caller}: `points[{k}]` needs x with {n} and u with {m} entries, got {x_.size} and {u_.size}")
            pts.append((float(t), x_, u_))
    f, h = compile_system(twin).bind()
    for t, x, u in pts:
        for fn_name, ours, label_of, theirs_fn in (
                ("f", f, lambda i: f"d({twin.states[i]})/dt", sys.dynamics),
                ("h", h, lambda i: f"output {twin.outputs[i]}", sys.output)):
            what = "updfcn" if fn_name == "f" else "outfcn"
            try:
                theirs = np.asarray(theirs_fn(t, x, u), dtype=float).reshape(-1)
            except Exception as e:  # noqa: BLE001 - a user function; report where it failed
                raise ModelError(f"{caller}: {sys.name!r}.{what} raised at t = {t:.6g}, x = {_fmt(x)}, u = {_fmt(u)}: "
                                 f"{type(e).__name__}: {e}. Pass `points` inside its domain") from e
            mine = np.asarray(ours(t, x, u), dtype=float).reshape(-1)
            if theirs.size != mine.size:
                raise ModelError(f"{caller}: {sys.name!r}.{what} returned {theirs.size} value(s) at t = {t:.6g}; the twin's "
                                 f"{fn_name} has {mine.size}")
            both_nan = np.isnan(mine) & np.isnan(theirs)
            bad = ~both_nan & ~(np.abs(mine - theirs) <= rtol * (1 + np.maximum(np.abs(mine), np.abs(theirs))))
            if bad.any():
                i = int(np.flatnonzero(bad)[0])
                raise ModelError(
                    f"{caller}: the twin's {fn_name} does not match {what} of the python-control system {sys.name!r}: "
                    f"{label_of(i)} at t = {t:.6g}, x = {_fmt(x)}, u = {_fmt(u)} is {mine[i]:.10g} in the twin and "
                    f"{theirs[i]:.10g} in {what} (difference {abs(mine[i] - theirs[i]):.3g}, tolerance "
                    f"{rtol * (1 + max(abs(mine[i]), abs(theirs[i]))):.3g}). Check the twin's equation and parameter values "
                    f"({dict(twin.params) or 'none'}) against {what} and the system's params ({dict(sys.params) or 'none'})")


def _fmt(v: np.ndarray) -> str:
    return "[" + ", ".join(f"{float(a):.6g}" for a in np.asarray(v).reshape(-1)) + "]"


def _labels(given: str | Sequence[str] | None, default: Sequence[str], n: int, kind: str) -> list[str]:
    if given is None:
        return list(default)
    if isinstance(given, str):
        if "{i}" not in given:
            raise ValueError(f"to_control: `{kind}` as a string must be a format with '{{i}}' (e.g. 'xhat[{{i}}]'), "
                             f"got {given!r}")
        return [given.format(i=i) for i in range(n)]
    out = [str(g) for g in given]
    if len(out) != n:
        raise ShapeError(f"to_control: `{kind}` must name {n} signal(s), got {len(out)}: {out}")
    return out


def to_control(observer: Any, *, plant: Any = None, dt: float | None = None, max_step: float | None = None,
               inputs: str | Sequence[str] | None = None, outputs: str | Sequence[str] = "xhat[{i}]",
               states: str | Sequence[str] | None = None, name: str | None = None) -> Any:
    r"""An nlobs observer as a ``control.NonlinearIOSystem``, ready for :func:`control.interconnect`.

    Inputs ``[y..., u...]`` (the plant's measured outputs, then its inputs), outputs
    ``xhat[0], xhat[1], ...`` (the estimate), states the observer's internal state z, as
    ``control.create_estimator_iosystem`` does. The initial state for a simulation is
    ``nlobs.Observer(design).initial_state(xhat0)``.

    - ``dt=None`` (continuous time, for continuous observers):
      :math:`\dot z = F(t, z, u, y),\ \hat x = H(t, z, u, y)`.
    - ``dt=T`` (discrete time, any observer, required for continuous-discrete ones such as
      the continuous-discrete EKF): a python-control system with sample period T whose state
      is the prior :math:`z^-_k` (before the update at :math:`t_k`):

      .. math::

          z^+_k = J(t_k, z^-_k, u_k, y_k),\quad \hat x_k = H(t_k, z^+_k, u_k, y_k),\quad
          z^-_{k+1} = \Phi_{RK4}(z^+_k;\ t_k \to t_k + T;\ u_k, y_k),

      which is exactly :meth:`nlobs.OnlineObserver.update` (and :func:`nlobs.estimate` with
      zero-order hold) at the regular sample times :math:`t_k`. Its output has direct
      feedthrough from :math:`y_k` (the update), as a sampled filter does. Close the loop with
      a discrete-time plant of the same ``dt`` (e.g. ``control.c2d(plant, T)``): python-control
      does not mix time bases in one interconnection.

    Parameters
    ----------
    observer : Observer, ObserverDesign or AbstractObserver
        The observer to wrap.
    plant : control.InputOutputSystem, optional
        The python-control plant: the observer's inputs take its output and input labels (so
        ``interconnect`` connects them by name); its sizes must match the observer's model.
    dt : float, optional
        Sample period of a discrete-time system (see above); None for continuous time.
    max_step : float, optional
        With `dt`: largest RK4 step within a period (default: one step per period).
    inputs : sequence of str or format string, optional
        Input labels (default: the plant's labels, else the model's output and input names).
    outputs : sequence of str or format string
        Output labels (default ``"xhat[{i}]"``).
    states : sequence of str or format string, optional
        State labels (default: the observer's internal state names).
    name : str, optional
        The system's name (default: the observer's name).

    Returns
    -------
    control.NonlinearIOSystem

    Raises
    ------
    PreconditionError
        For a continuous-discrete observer without `dt`, or `max_step` without `dt`.
    ShapeError
        When the plant's or the given labels' sizes differ from the observer's model.
    ValueError
        For a `dt` or `max_step` that is not positive and finite.

    Examples
    --------
    >>> import nlobs
    >>> sys_ = nlobs.System.lti([[0, 1], [0, 0]], [[0], [1]], [[1, 0]])
    >>> est = to_control(nlobs.design_luenberger(sys_, poles=[-2, -3]), name="est")
    >>> est.input_labels, est.output_labels
    (['y1', 'u1'], ['xhat[0]', 'xhat[1]'])
    """
    ct = _control()
    caller = "to_control"
    obs: AbstractObserver = as_observer(observer)
    s = obs.system
    nx, nu, ny, nz = s.n_states, s.n_inputs, s.n_outputs, obs.n_z
    default_in = [*s.outputs, *s.inputs]
    if plant is not None:
        if not isinstance(plant, ct.InputOutputSystem):
            raise TypeError(f"{caller}: `plant` must be a python-control system, got {type(plant).__name__}")
        if (plant.noutputs, plant.ninputs) != (ny, nu):
            raise ShapeError(f"{caller}: the plant {plant.name!r} has {plant.noutputs} output(s) and {plant.ninputs} input(s); "
                             f"the observer's model {s.name!r} has {ny} and {nu}")
        default_in = [*plant.output_labels, *plant.input_labels]
    in_labels = _labels(inputs, default_in, ny + nu, "inputs")
    out_labels = _labels(outputs, [], nx, "outputs")
    st_labels = _labels(states, list(obs.design.z_names), nz, "states")
    label = name or getattr(obs, "name", None) or obs.design.method

    def split(v: Any) -> tuple[np.ndarray, np.ndarray]:
        v = np.asarray(v, dtype=float).reshape(-1)
        return v[:ny], v[ny:]

    if s.is_discrete:   # a map's observer steps with the map: its period is the model's
        if dt is not None and abs(float(dt) - s.sample_time) > 1e-12 * s.sample_time:
            raise PreconditionError(f"{caller}: the observer {label!r} runs on the discrete-time model {s.name!r} with "
                                    f"sample_time = {s.sample_time:g}; dt = {dt!r} differs (leave dt out)")
        if max_step is not None:
            raise PreconditionError(f"{caller}: `max_step` does not apply to a discrete-time model's observer (no flow "
                                    "between samples)")
        dt = s.sample_time
    if dt is None:
        if max_step is not None:
            raise PreconditionError(f"{caller}: `max_step` applies to a discrete-time system; give `dt` too, or leave "
                                    "`max_step` out (python-control integrates the continuous system itself)")
        if obs.sampled:
            raise PreconditionError(
                f"{caller}: the observer {label!r} is continuous-discrete (it updates at sample instants), so it has no "
                "continuous-time form; pass dt=<sample period> for a discrete-time system (and close the loop with "
                "a plant discretised at that period)")

        def updfcn(t: float, z: Any, v: Any, params: Any) -> np.ndarray:
            y, u = split(v)
            return obs.rhs(t, z, u, y)

        def outfcn(t: float, z: Any, v: Any, params: Any) -> np.ndarray:
            y, u = split(v)
            return obs.estimate(t, z, u, y)

        return ct.nlsys(updfcn, outfcn, inputs=in_labels, outputs=out_labels, states=st_labels, dt=0, name=label)

    T = check_positive(dt, "dt", "to_control")
    n_sub = 1 if max_step is None else max(1, math.ceil(T / check_positive(max_step, "max_step", "to_control") - 1e-9))
    last: dict[str, Any] = {}

    def posterior(t: float, z: Any, v: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        z = np.asarray(z, dtype=float).reshape(-1)
        y, u = split(v)
        key = (float(t), z.tobytes(), y.tobytes(), u.tobytes())
        if last.get("key") != key:  # python-control asks for the output and the update at the same point
            last["key"], last["value"] = key, obs.update(t, z, u, y) if obs.sampled else z
        return last["value"], u, y

    def dupdfcn(t: float, z: Any, v: Any, params: Any) -> np.ndarray:
        zp, u, y = posterior(t, z, v)
        return obs.step(t, zp, T, u, y, substeps=n_sub)

    def doutfcn(t: float, z: Any, v: Any, params: Any) -> np.ndarray:
        zp, u, y = posterior(t, z, v)
        return obs.estimate(t, zp, u, y)

    return ct.nlsys(dupdfcn, doutfcn, inputs=in_labels, outputs=out_labels, states=st_labels, dt=T, name=label)
