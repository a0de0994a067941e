"""Models and published identifiability results, transcribed from two public test suites.

Each entry is a model and the results its source publishes for it; nothing here comes from nlobs.
Sources (repository @ commit, file):

- ``SI``: SciML/StructuralIdentifiability.jl @ b7bff91634575095369190ca7d418fe41f98cac2
  - ``SI/identifiability``: test/bodies/identifiability.jl (``assess_identifiability`` verdicts:
    globally / locally / nonidentifiable for the listed functions)
  - ``SI/functions``: test/bodies/identifiable_functions.jl (``find_identifiable_functions``: a set of
    generators of the field of identifiable functions; ``with_states`` when states are included)
  - ``SI/me``: test/bodies/local_identifiability_me.jl (multi-experiment: the number of experiments
    after which the identifiable parameters stop growing, and which parameters are then identifiable)
- ``SIAN``: alexeyovchinnikov/SIAN-Julia @ a391de1bf66cf945cafa30c1397b69d09ca1f733,
  test/io_tests.jl and test/test_id_with_weights_mtk.jl (``identifiability_ode``: globally /
  locally_not_globally / nonidentifiable for every parameter and initial condition).

Names that nlobs reserves are renamed (I -> In, E -> Ex, lambda -> lam); ``case`` quotes the test
case so it can be found in the file. Every state and every parameter is an unknown (parameters
enter with "all"), as in the sources. ``verdicts`` maps a name or a function to the published
verdict ("globally", "locally", "non"); ``ident`` is a published generating set of the identifiable
functions (of the parameters, or of parameters and states when ``with_states``); ``me`` is the
published number of experiments and ``me_identifiable`` the parameters identifiable with them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

SI = "SciML/StructuralIdentifiability.jl@b7bff91634575095369190ca7d418fe41f98cac2"
SIAN = "alexeyovchinnikov/SIAN-Julia@a391de1bf66cf945cafa30c1397b69d09ca1f733"


@dataclass(frozen=True)
class Published:
    name: str
    source: str
    case: str
    states: dict[str, str]
    outputs: dict[str, str]
    params: tuple[str, ...]
    inputs: tuple[str, ...] = ()
    verdicts: dict[str, str] = field(default_factory=dict)
    ident: tuple[str, ...] | None = None
    with_states: bool = False
    me: int | None = None
    me_identifiable: dict[str, bool] = field(default_factory=dict)

    def system(self):
        from nlobs import System

        return System(states=list(self.states), f=list(self.states.values()), outputs=list(self.outputs),
                      h=list(self.outputs.values()), inputs=list(self.inputs),
                      params={p: 1.0 for p in self.params}, name=self.name)


def _p(*names: str) -> tuple[str, ...]:
    return tuple(names)


G, L, N = "globally", "locally", "non"

MODELS: list[Published] = [
    # ------------------------------------------------------------------ SI/identifiability
    Published("two_compartment", f"{SI} test/bodies/identifiability.jl", "# 2-compartiment model",
              {"x0": "-(a01 + a21)*x0 + a12*x1", "x1": "a21*x0 - a12*x1"}, {"y": "x0"}, _p("a01", "a21", "a12"),
              verdicts={"a01": N, "a21": N, "a12": N, "a01*a12": G, "a01 + a12 + a21": G,
                        "(a01 + a12 + a21)/(a01*a12)": G}),
    Published("no_parameters", f"{SI} test/bodies/identifiability.jl", "# No parameters no worry",
              {"x1": "x1", "x2": "x2"}, {"y": "x1 + x2"}, (),
              verdicts={"x1": N, "x2": N, "x1 + x2": G}),
    Published("lv_input", f"{SI} test/bodies/identifiability.jl", "x0' = a*x0 - b*x0*x1 + u",
              {"x0": "a*x0 - b*x0*x1 + u", "x1": "c*x1 + d*x0*x1"}, {"y": "x0"}, _p("a", "b", "c", "d"), ("u",),
              verdicts={"a": G, "b": N, "c": G, "d": G, "b*x1": G, "x0": G, "x1": N}),
    Published("siwr", f"{SI} test/bodies/identifiability.jl", "S' = mu - bi*S*I - bw*S*W - mu*S + a*R",
              {"S": "mu - bi*S*In - bw*S*W - mu*S + a*R", "In": "bw*S*W + bi*S*In - (gam + mu)*In",
               "W": "xi*(In - W)", "R": "gam*In - (mu + a)*R"}, {"y": "k*In"}, _p("mu", "bi", "bw", "a", "xi", "gam", "k"),
              verdicts={"mu": G, "bi": G, "bw": G, "a": G, "xi": G, "gam": G, "gam + mu": G, "k": G}),
    Published("goodwin", f"{SI} test/bodies/identifiability.jl", "x1' = -b*x1 + 1/(c + x4)",
              {"x1": "-b*x1 + 1/(c + x4)", "x2": "alpha*x1 - beta*x2", "x3": "gama*x2 - delta*x3",
               "x4": "sigma*x4*(gama*x2 - delta*x3)/x3"}, {"y": "x1"},
              _p("b", "c", "alpha", "beta", "gama", "delta", "sigma"),
              verdicts={"b": G, "c": G, "alpha": N, "beta": L, "delta": L, "gama": N, "beta + delta": G,
                        "beta*delta": G}),
    Published("rational_outputs", f"{SI} test/bodies/identifiability.jl", "x1' = (1 + x1^2)//2",
              {"x1": "(1 + x1**2)/2", "x2": "(1 - x1**2)/(1 + x1**2)"},
              {"y1": "2*x1/(b*(1 + x1**2))", "y2": "x2"}, _p("b"), verdicts={"b": G, "x1": G, "x2": G}),
    Published("two_state_no_input", f"{SI} test/bodies/identifiability.jl", "x2' = -a2*x2 - a21*x2, y1 = x1 (no input)",
              {"x1": "-a1*x1 + a21*x2", "x2": "-a2*x2 - a21*x2"}, {"y1": "x1"}, _p("a1", "a2", "a21"),
              verdicts={"a1": L, "a2": N, "a21": N}),
    Published("two_state_input", f"{SI} test/bodies/identifiability.jl", "x2' = -a2*x2 - a21*x2 + u",
              {"x1": "-a1*x1 + a21*x2", "x2": "-a2*x2 - a21*x2 + u"}, {"y1": "x1"}, _p("a1", "a2", "a21"), ("u",),
              verdicts={"a1": L, "a2": L, "a21": G, "a2 + a1": G, "a2*(a1 - a21)": G}),
    Published("three_compartment", f"{SI} test/bodies/identifiability.jl", "x1' = -(a21 + a31 + a01)*x1 + ...",
              {"x1": "-(a21 + a31 + a01)*x1 + a12*x2 + a13*x3 + u", "x2": "a21*x1 - a12*x2",
               "x3": "a31*x1 - a13*x3"}, {"y": "x1"}, _p("a21", "a31", "a01", "a12", "a13"), ("u",),
              verdicts={"x1": G, "x2": L, "x3": L, "a31 + a21": G, "(a21 - a31)/(a12 - a13)": G}),
    Published("seir_n", f"{SI} test/bodies/identifiability.jl", "S' = -b*S*I/N, y2 = N",
              {"S": "-b*S*In/N", "Ex": "b*S*In/N - nu*Ex", "In": "nu*Ex - a*In"}, {"y1": "In", "y2": "N"},
              _p("b", "N", "nu", "a"),
              verdicts={"b": G, "N": G, "In": G, "a": L, "nu": L, "S": L, "Ex": L, "a*nu": G, "a + nu": G}),
    # ------------------------------------------------------------------ SIAN io_tests
    Published("sian_lv", f"{SIAN} test/io_tests.jl", "x1' = a*x1 - b*x1*x2 (first case)",
              {"x1": "a*x1 - b*x1*x2", "x2": "-c*x2 + d*x1*x2"}, {"y1": "x1"}, _p("a", "b", "c", "d"),
              verdicts={"a": G, "c": G, "d": G, "x1": G, "b": N, "x2": N}),
    Published("sian_quadratic_output", f"{SIAN} test/io_tests.jl", "y2 = a*x1 + a^2",
              {"x1": "0"}, {"y1": "x1", "y2": "a*x1 + a**2"}, _p("a"), verdicts={"x1": G, "a": L}),
    Published("sian_seir_state_n", f"{SIAN} test/io_tests.jl", "N'(t) = 0, y2 = N(t)",
              {"S": "-b*S*In/N", "Ex": "b*S*In/N - nu*Ex", "In": "nu*Ex - a*In", "N": "0"}, {"y1": "In", "y2": "N"},
              _p("b", "nu", "a"),
              verdicts={"b": G, "In": G, "N": G, "nu": L, "S": L, "a": L, "Ex": L}),
    Published("sian_abc_reaction", f"{SIAN} test/io_tests.jl", "xA' = -k1*xA, ..., y2 = eA*xA + eB*xB + eC*xC",
              {"xA": "-k1*xA", "xB": "k1*xA - k2*xB", "xC": "k2*xB", "eA": "0", "eC": "0"},
              {"y1": "xC", "y2": "eA*xA + eB*xB + eC*xC", "y3": "eA", "y4": "eC"}, _p("k1", "k2", "eB"),
              verdicts={"xC": G, "eC": G, "eA": G, "xA": L, "k1": L, "xB": L, "eB": L, "k2": L}),
    Published("sian_two_compartment_mtk", f"{SIAN} test/test_id_with_weights_mtk.jl", "D(x0) ~ -(a01 + a21)*x0 + a12*x1",
              {"x0": "-(a01 + a21)*x0 + a12*x1", "x1": "a21*x0 - a12*x1"}, {"y1": "x0"}, _p("a01", "a21", "a12"),
              verdicts={"a12": N, "a21": N, "x1": N, "a01": N, "x0": G}),
    # ------------------------------------------------------------------ SI/functions (parameters)
    Published("linear_input", f"{SI} test/bodies/identifiable_functions.jl", "x'(t) = a*x(t) + u(t) (with_states)",
              {"x": "a*x + u"}, {"y": "x"}, _p("a"), ("u",), ident=("a", "x"), with_states=True),
    Published("translation_a", f"{SI} test/bodies/identifiable_functions.jl", "x1'(t) = a, x2'(t) = -a",
              {"x1": "a", "x2": "-a"}, {"y": "x1 + x2"}, _p("a"), ident=()),
    Published("shift_a", f"{SI} test/bodies/identifiable_functions.jl", "x1' = x2 - a, x2' = x1 + a",
              {"x1": "x2 - a", "x2": "x1 + a"}, {"y": "x1 + x2"}, _p("a"), ident=()),
    Published("theta_x2_squared", f"{SI} test/bodies/identifiable_functions.jl", "x1' = Θ*x2^2, x2' = u",
              {"x1": "th*x2**2", "x2": "u"}, {"y": "x1"}, _p("th"), ("u",), ident=("th",)),
    Published("michaelis_menten_output_scale", f"{SI} test/bodies/identifiable_functions.jl",
              "x' = (-V_m*x)/(k_m + x) + k01*x, y = c*x",
              {"x": "-Vm*x/(km + x) + k01*x"}, {"y": "c*x"}, _p("Vm", "km", "k01", "c"), ident=("k01", "c*km", "Vm*c")),
    Published("bc_product", f"{SI} test/bodies/identifiable_functions.jl", "x' = a*x + b*u, y = c*x (with_states)",
              {"x": "a*x + b*u"}, {"y": "c*x"}, _p("a", "b", "c"), ("u",), ident=("a", "b*c", "x*c"), with_states=True),
    Published("two_compartment_funcs", f"{SI} test/bodies/identifiable_functions.jl", "# 2-compartiment model",
              {"x0": "-(a01 + a21)*x0 + a12*x1", "x1": "a21*x0 - a12*x1"}, {"y": "x0"}, _p("a01", "a21", "a12"),
              ident=("a01*a12", "a01 + a12 + a21")),
    Published("bellman_astrom", f"{SI} test/bodies/identifiable_functions.jl", "Example 2 from On Structural Identifiability",
              {"x1": "-(k1 + k2)*x1 + k3*x2 + u", "x2": "k2*x1 - (k3 + k4)*x2"}, {"y": "x1"}, _p("k1", "k2", "k3", "k4"),
              ("u",), ident=("k1 + k2", "k3 + k4", "k2*k3")),
    Published("diagonal_three", f"{SI} test/bodies/identifiable_functions.jl",
              "Diagonal with simple spectrum and observable states (with_states)",
              {"x1": "l1*x1 + b1*u1", "x2": "l2*x2 + b2*u2", "x3": "l3*x3 + b3*u3"}, {"y": "x1 + x2 + x3"},
              _p("l1", "l2", "l3", "b1", "b2", "b3"), ("u1", "u2", "u3"),
              ident=("l1", "l2", "l3", "b1", "b2", "b3", "x1", "x2", "x3"), with_states=True),
    Published("chain_controlled_x1", f"{SI} test/bodies/identifiable_functions.jl", "If we observe x1 and control x1",
              {"x1": "-a1*x1 + b1*x2 + u", "x2": "-(a2 + b1)*x2 + a1*x1 + b2*x3", "x3": "-b2*x3 + a2*x2"},
              {"y": "x1"}, _p("a1", "a2", "b1", "b2"), ("u",), ident=("a1", "a2", "b1", "b2")),
    Published("chain_controlled_x3", f"{SI} test/bodies/identifiable_functions.jl", "If we observe x1 and control x3",
              {"x1": "-a1*x1 + b1*x2", "x2": "-(a2 + b1)*x2 + a1*x1 + b2*x3", "x3": "-b2*x3 + a2*x2 + u"},
              {"y": "x1"}, _p("a1", "a2", "b1", "b2"), ("u",), ident=("b1*b2", "a1 + a2 + b1 + b2", "a1*a2 + a1*b2")),
    Published("quadratic_p1p4", f"{SI} test/bodies/identifiable_functions.jl",
              "Example 3 from On the identifiability and distinguishability of nonlinear parametric models",
              {"x1": "p1*x1**2 + p2*x1*x2", "x2": "p3*x1**2 + p4*x1*x2"}, {"y": "x1"}, _p("p1", "p2", "p3", "p4"),
              ident=("p1 + p4", "-p2*p3 + p4*p1")),
    Published("goodwin_funcs", f"{SI} test/bodies/identifiable_functions.jl", "# Goowdin oscillator",
              {"x1": "-b*x1 + 1/(c + x4)", "x2": "alpha*x1 - beta*x2", "x3": "gama*x2 - delta*x3",
               "x4": "sigma*x4*(gama*x2 - delta*x3)/x3"}, {"y": "x1"},
              _p("b", "c", "alpha", "beta", "gama", "delta", "sigma"),
              ident=("sigma", "delta + beta", "c", "b", "delta*beta")),
    Published("sirs_forced", f"{SI} test/bodies/identifiable_functions.jl", "# SIRS forced",
              {"s": "mu - mu*s - b0*(1 + b1*x1)*i*s + g*r", "i": "b0*(1 + b1*x1)*i*s - (nu + mu)*i",
               "r": "nu*i - (mu + g)*r", "x1": "-M*x2", "x2": "M*x1"}, {"y1": "i", "y2": "r"},
              _p("mu", "b0", "b1", "g", "nu", "M"), ident=("g", "mu", "b0", "nu", "M**2")),
    Published("seir_1_io", f"{SI} test/bodies/identifiable_functions.jl", "# SEIR_1_io",
              {"S": "-beta*S*In", "Ex": "beta*S*In - v*Ex", "In": "v*Ex - psi*In - (1 - psi)*gamma*In",
               "R": "gamma*Q + (1 - psi)*gamma*In", "Q": "-gamma*Q + psi*In"}, {"y1": "Q"},
              _p("beta", "v", "psi", "gamma"), ident=("gamma*psi - psi*v", "beta/psi", "gamma", "psi*v - psi - v")),
    Published("biohydrogenation", f"{SI} test/bodies/identifiable_functions.jl", "# Biohydrogenation_io",
              {"x5": "(k5*k8*x4 + k5*x6*x4 + k5*x5*x4 - k6*x5*k7 - x5*k7*x4)/(k8*k6 + k8*x4 + k6*x6 + k6*x5 + x6*x4 + x5*x4)",
               "x7": "(k9*k10*x6 - k9*x6**2)/k10", "x4": "(-k5*x4)/(k6 + x4)",
               "x6": "(-k8*k9*k10*x6 + k8*k9*x6**2 - k9*k10*x6**2 - k9*k10*x6*x5 + k9*x6**3 + k9*x6**2*x5 + k10*x5*k7)"
                     "/(k8*k10 + k10*x6 + k10*x5)"},
              {"y1": "x4", "y2": "x5"}, _p("k5", "k6", "k7", "k8", "k9", "k10"),
              ident=("k7", "k5", "k6", "k10*k9", "k9**2", "k10 + 2*k8")),
    Published("sliqr", f"{SI} test/bodies/identifiable_functions.jl", "# SLIQR",
              {"S": "-b*In*S*Ninv - S*Ninv*u", "In": "-In*g + s*Q + a*L", "L": "b*In*S*Ninv - a*L",
               "Q": "-e*In*g + In*g - s*Q"}, {"y": "In*Ninv"}, _p("b", "Ninv", "g", "s", "a", "e"), ("u",),
              ident=("a*g + e*g*s - g*s", "b", "a + g", "a*e*g", "s", "Ninv")),
    Published("stat5", f"{SI} test/bodies/identifiable_functions.jl", "# STAT-5 model",
              {"x1": "-k1*x1*EpoR_A", "x2": "k1*x1*EpoR_A - k2*x2**2", "x3": "-k3*x3 + 0.5*k2*x2**2", "x4": "k3*x3"},
              {"y1": "k5*(x2 + 2*x3)", "y2": "k6*(x1 + x2 + 2*x3)", "y3": "k7*EpoR_A"},
              _p("k1", "k2", "k3", "k5", "k6", "k7", "EpoR_A"),
              ident=("k2/k6", "k3", "EpoR_A*k7", "EpoR_A*k1", "k5/k6")),
    # ------------------------------------------------------------------ SI/functions (with states)
    Published("exp_growth_state", f"{SI} test/bodies/identifiable_functions.jl", "x'(t) = x(t), y(t) = x(t)",
              {"x": "x"}, {"y": "x"}, (), ident=("x",), with_states=True),
    Published("lv_states", f"{SI} test/bodies/identifiable_functions.jl", "x1' = a*x1 - b*x1*x2 (with_states)",
              {"x1": "a*x1 - b*x1*x2", "x2": "-c*x2 + d*x1*x2"}, {"y": "x1"}, _p("a", "b", "c", "d"),
              ident=("x1", "c", "d", "a", "b*x2"), with_states=True),
    Published("theta_x2_const", f"{SI} test/bodies/identifiable_functions.jl", "x1' = x1 + Θ*x2, x2' = 0",
              {"x1": "x1 + th*x2", "x2": "0"}, {"y": "x1"}, _p("th"), ident=("x1", "x2*th"), with_states=True),
    Published("alpha_chain", f"{SI} test/bodies/identifiable_functions.jl", "x1' = α*x2, x2' = x3, x3' = C",
              {"x1": "alpha*x2", "x2": "x3", "x3": "C"}, {"y": "x1"}, _p("alpha", "C"),
              ident=("x1", "alpha*x2", "alpha*x3", "alpha*C"), with_states=True),
    Published("rotation_norm", f"{SI} test/bodies/identifiable_functions.jl", "y(t) = (x1^2 + x2^2) // 2",
              {"x1": "alpha*(x1 - x2)", "x2": "alpha*(x1 + x2)"}, {"y": "(x1**2 + x2**2)/2"}, _p("alpha"),
              ident=("alpha", "x1**2 + x2**2"), with_states=True),
    Published("llw1987", f"{SI} test/bodies/identifiable_functions.jl", "# llw1987 model",
              {"x1": "-p1*x1 + p2*u", "x2": "-p3*x2 + p4*u", "x3": "-(p1 + p3)*x3 + (p4*x1 + p2*x2)*u"},
              {"y1": "x3"}, _p("p1", "p2", "p3", "p4"), ("u",),
              ident=("x3", "x2*x1", "p3*p1", "p2*p4", "p3 + p1", "p2*x2 + p4*x1", "x1*p1*p4 + x2*p2*p3"),
              with_states=True),
    Published("bruno2016", f"{SI} test/bodies/identifiable_functions.jl", "# Bruno2016 model",
              {"beta": "-kbeta*beta", "cry": "-cry*kcrybeta - cry*kcryOH", "zea": "-zea*kzea",
               "beta10": "cry*kcryOH - beta10*kbeta10 + kbeta*beta",
               "OHbeta10": "cry*kcrybeta + zea*kzea - OHbeta10*kOHbeta10",
               "betaio": "cry*kcrybeta + beta10*kbeta10 + kbeta*beta",
               "OHbetaio": "cry*kcryOH + zea*kzea + OHbeta10*kOHbeta10"},
              {"y1": "beta", "y2": "beta10"}, _p("kbeta", "kcrybeta", "kcryOH", "kzea", "kbeta10", "kOHbeta10"),
              ident=("beta10", "beta", "kbeta", "kbeta10", "cry*kcryOH", "kcrybeta + kcryOH"), with_states=True),
    Published("sum_of_exponentials", f"{SI} test/bodies/identifiable_functions.jl", "x1'(t) = x1, x2'(t) = x2 (with_states)",
              {"x1": "x1", "x2": "x2"}, {"y": "x1 + x2"}, (), ident=("x1 + x2",), with_states=True),
    Published("seuir", f"{SI} test/bodies/identifiable_functions.jl", "# SEUIR model from the reparametrization docs",
              {"S": "-b*(U + In)*S/N", "Ex": "b*(U + In)*S/N - g*Ex", "U": "(1 - a)*g*Ex - d*U", "In": "a*g*Ex - d*In"},
              {"y": "In"}, _p("b", "N", "g", "a", "d"),
              ident=("In", "d", "g", "S*a", "Ex*a", "U*a + In*a", "N*a/b"), with_states=True),
    Published("square_output", f"{SI} test/bodies/identifiable_functions.jl", "x'(t) = alpha*x(t)^2, y(t) = x(t)^2",
              {"x": "alpha*x**2"}, {"y": "x**2"}, _p("alpha"), ident=("alpha**2", "x*alpha"), with_states=True),
    Published("mbs2009_section6", f"{SI} test/bodies/identifiable_functions.jl", "# Section 6 (with_states)",
              {"x1": "-(k01 + k21)*x1 + k12*x2 + u", "x2": "k21*x1 - (k02 + k12)*x2"}, {"y": "x1/v"},
              _p("k01", "k21", "k12", "k02", "v"), ("u",),
              ident=("v", "x1", "k02 + k12", "k01 + k21", "k12*k21", "x2*k12"), with_states=True),
    Published("mbs2009_example1", f"{SI} test/bodies/identifiable_functions.jl", "# Example 1 (with_states)",
              {"x1": "-(k21 + V_M/(K_M + x1))*x1 + k12*x2 + b1*u", "x2": "k21*x1 - (k02 + k12)*x2"}, {"y": "c*x1"},
              _p("k21", "V_M", "K_M", "k12", "b1", "k02", "c"), ("u",),
              ident=("k21", "k12", "k02", "b1*c", "V_M*c", "K_M*c", "x2*c", "x1*c"), with_states=True),
    Published("mbs2009_example3", f"{SI} test/bodies/identifiable_functions.jl", "# Example 3 (with_states)",
              {"x1": "-a31*x1 + a13*x3 + u", "x2": "-a42*x2 + a24*x4", "x3": "a31*x1 - (a03 + a13 + a43)*x3",
               "x4": "a42*x2 + a43*x3 - (a04 + a24)*x4"}, {"y1": "x1", "y2": "x2"},
              _p("a31", "a13", "a42", "a24", "a03", "a43", "a04"), ("u",),
              ident=("a31", "a13", "x3", "x2", "x1", "a03 + a43", "a04 + a24 + a42", "a24*a43", "a04*a42",
                     "x2*a42 - x4*a24"), with_states=True),
    Published("mbs2009_example4", f"{SI} test/bodies/identifiable_functions.jl", "# Example 4 (with_states)",
              {"S": "mu*N - S*(mu + beta/N*In)", "In": "In*(beta/N*S - mu - nu)"}, {"y": "k*In"},
              _p("mu", "N", "beta", "nu", "k"), ident=("nu", "mu", "beta", "N*k", "In*k", "S*k"), with_states=True),
    Published("mbs2009_example5", f"{SI} test/bodies/identifiable_functions.jl", "# Example 5 (with_states)",
              {"x1": "p1*x1 - p2*x1*x2", "x2": "p3*x2*(1 - p4*x2) + p5*x1*x2"}, {"y": "x1"},
              _p("p1", "p2", "p3", "p4", "p5"), ident=("p5", "p3", "p1", "x1", "x2*p4", "p2/p4"), with_states=True),
    Published("mbs2009_example6", f"{SI} test/bodies/identifiable_functions.jl", "# Example 6 (parameters)",
              {"x1": "-beta*x1*x4 - d*x1 + s", "x2": "beta*q1*x1*x4 - k1*x2 - mu1*x2",
               "x3": "beta*q2*x1*x4 + k1*x2 - mu2*x3", "x4": "-c*x4 + k2*x3"}, {"y1": "x1", "y2": "x4"},
              _p("beta", "d", "s", "q1", "k1", "mu1", "q2", "mu2", "c", "k2"),
              ident=("s", "d", "beta", "c + k1 + mu1 + mu2", "k2*q2", "c*k1 + c*mu1 + c*mu2 + k1*mu2 + mu1*mu2",
                     "c*k1*mu2 + c*mu1*mu2", "k1*k2*q1 + k1*k2*q2 + k2*mu1*q2")),
    Published("mbs2011_section11", f"{SI} test/bodies/identifiable_functions.jl", "# From Section 11 (with_states)",
              {"T": "lam - rho*T - beta*T*V", "Tast": "beta*T*V - delta*Tast", "V": "N*delta*Tast - c*V"}, {"y": "V"},
              _p("lam", "rho", "beta", "delta", "N", "c"),
              ident=("rho", "beta", "V", "c + delta", "c*delta", "T/lam", "N*delta*lam", "Tast*N*delta + V*delta"),
              with_states=True),
    # ------------------------------------------------------------------ SI/me
    Published("me_two_compartment", f"{SI} test/bodies/local_identifiability_me.jl", "x0'(t) = -(a01 + a21)*x0 ...",
              {"x0": "-(a01 + a21)*x0 + a12*x1", "x1": "a21*x0 - a12*x1"}, {"y": "x0"}, _p("a01", "a21", "a12"),
              me=1, me_identifiable={"a01": False, "a21": False, "a12": False}),
    Published("me_example_7_7", f"{SI} test/bodies/local_identifiability_me.jl", "# Example 7.7",
              {"x0": "0", "x1": "x0*x1 + mu1*x0 + mu2"}, {"y": "x1"}, _p("mu1", "mu2"),
              me=2, me_identifiable={"mu1": True, "mu2": True}),
    Published("me_example_7_8", f"{SI} test/bodies/local_identifiability_me.jl", "# Example 7.8",
              {"S": "-b*S*In/N", "Ex": "b*S*In/N - nu*Ex", "In": "nu*Ex - a*In", "c": "0"},
              {"y1": "c*In + d*Ex", "y2": "c", "y3": "N"}, _p("b", "N", "nu", "a", "d"),
              me=1, me_identifiable={"b": True, "nu": True, "d": True, "a": True}),
    Published("me_zero_replicas", f"{SI} test/bodies/local_identifiability_me.jl", "# example with 0 replicas required",
              {"x": "a*z", "z": "a*z**2"}, {"y": "x"}, _p("a"), me=0, me_identifiable={"a": False}),
]


def linear_compartment(kind: str, n: int) -> Published:
    """SI/me's linear compartment models (``_linear_compartment_model``): rates a_ij + b_ij x0, x0 constant, observed.

    Published bounds (test/bodies/local_identifiability_me.jl, "checking bounds"): cyclic 3 for
    n = 3..8; catenary and mammillary 4 for n = 3 and 5 for n = 4..8.
    """
    if kind == "cycle":
        graph = [[(i % n) + 1] for i in range(1, n + 1)]
        bound = 3
    elif kind == "catenary":
        graph = [[j for j in (i - 1, i + 1) if 1 <= j <= n] for i in range(1, n + 1)]
        bound = 4 if n == 3 else 5
    elif kind == "mammillary":
        graph = [list(range(2, n + 1))] + [[1] for _ in range(2, n + 1)]
        bound = 4 if n == 3 else 5
    else:
        raise ValueError(kind)
    eq = {f"x{i}": [] for i in range(1, n + 1)}
    params = []
    for i in range(1, n + 1):
        for j in graph[i - 1]:
            rate = f"(a_{i}_{j} + b_{i}_{j}*x0)"
            params += [f"a_{i}_{j}", f"b_{i}_{j}"]
            if i != j:
                eq[f"x{j}"].append(f"+ x{i}*{rate}")
                eq[f"x{i}"].append(f"- x{i}*{rate}")
            else:
                eq[f"x{i}"].append(f"- x{i}*{rate}")
    params += ["a_1_0", "b_1_0"]
    eq["x1"].append("- x1*(a_1_0 + b_1_0*x0)")
    states = {"x0": "0", **{k: " ".join(v) or "0" for k, v in eq.items()}}
    return Published(f"me_{kind}_{n}", f"{SI} test/bodies/local_identifiability_me.jl", f"{kind}, n = {n} (bound)",
                     states, {"y1": "x1", "y2": "x0"}, tuple(params), me=bound)


BY_NAME = {m.name: m for m in MODELS}
