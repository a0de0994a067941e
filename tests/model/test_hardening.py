"""Model files and symbolic work at the edges (issue 10): each reproduced failure, now a clear error."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
import sympy as sp

import nlobs
from nlobs import ModelError, ModelFileError, System, loads_model
from nlobs.errors import SymbolicBudgetError
from nlobs.model import parse_expression, symbol
from nlobs.model._budget import (MAX_TERMS, SymbolicTimeLimit, expand, expanded_terms, symbolic_budget,
                                 symbolic_time_limit, tree_size)
from nlobs.model._expr import ExpressionError

X = symbol("x")
BASE = 'states = ["x"]\noutputs = ["y"]\n[dynamics]\nx = "-x"\n[output]\ny = "x"\n'


# -- exponents ---------------------------------------------------------------------------------
@pytest.mark.parametrize("text, exponent", [
    ("((x**64)**64)**64", "4096"),  # SymPy combines nested integer powers: stopped at the first, x**4096
    ("(x**64)**64", "4096"),
    ("x**64*x**64", "128"),  # and products of powers of the same base
    ("((x+1)**64)**64", "4096"),
    ("x**40 * x**30", "70"),
])
def test_exponent_limit_holds_after_sympy_combines_powers(text, exponent):
    with pytest.raises(ExpressionError, match=f"exponent {exponent} .*exceeds 64"):
        parse_expression(text, {"x": X})


def test_exponent_limit_still_allows_the_limit_itself():
    assert parse_expression("x**32 * x**32", {"x": X}) == X**64
    with pytest.raises(ExpressionError, match="150 exceeds 64"):
        parse_expression("x**(64**150)", {"x": X})


# -- names and labels ----------------------------------------------------------------------------
@pytest.mark.parametrize("bad", ["x\n", "x\r\n", "x ", "1x", "x-y", "lambda"])
def test_state_names_are_whole_identifiers(bad):
    with pytest.raises(ModelError, match="not valid"):
        System(states=[bad], f=["0"], outputs=["y"], h=["0"])


@pytest.mark.parametrize("name", ["I", "E", "N", "S", "O", "Q", "beta", "gamma", "oo", "zoo", "nan", "Symbol"])
def test_sympy_names_are_free_for_the_user(name):
    """SEIR-style names: the parser builds its own symbols, so SymPy's I, E, N, S mean nothing special."""
    s = System(states=[name, "R"], f=[f"-2*{name}", f"{name} - R"], outputs=["y"], h=["R"], name="seir")
    assert s.f[0] == -2 * symbol(name) and s.f[0].free_symbols == {symbol(name)}
    run = nlobs.simulate(s, None, t_final=1.0, dt=1e-3, x0=[1.0, 0.0], engine="vm")
    assert abs(run.x[-1, 0] - math.exp(-2.0)) < 1e-10  # x' = -2x from 1: e^-2 (RK4 at dt = 1e-3)
    rep = nlobs.analyze(s)
    assert rep.observable


def test_seir_with_i_e_n_s_through_a_file_analysis_and_ekf():
    text = '''
    name = "seir"
    states = ["S", "E", "I", "R"]
    outputs = ["y"]
    [parameters]
    beta = 0.5
    sigma = 0.2
    gamma = 0.1
    N = 1.0
    [dynamics]
    S = "-beta*S*I/N"
    E = "beta*S*I/N - sigma*E"
    I = "sigma*E - gamma*I"
    R = "gamma*I"
    [output]
    y = "I"
    [observers.ekf]
    kind = "ekf"
    Q = [[1e-6, 0, 0, 0], [0, 1e-6, 0, 0], [0, 0, 1e-6, 0], [0, 0, 0, 1e-6]]
    R = [[1e-4]]
    '''
    mf = loads_model(text.replace("\n    ", "\n"))
    assert mf.system.states == ("S", "E", "I", "R")
    rep = nlobs.analyze(mf.system)
    assert "R" not in rep.observable_states and "I" in rep.observable_states  # R never reaches y
    d = nlobs.design.design_from_config(mf.observers["ekf"])
    assert d.system.states == ("S", "E", "I", "R")


@pytest.mark.parametrize("name, reason", [
    ("evil */ int main(){} /*", r"\*/"),
    ("tab\there", "U\\+0009"),
    ("clear\x1b[2J", "U\\+001B"),
    ("line\nbreak", "U\\+000A"),
    ("bidi\u202eevil", "U\\+202E"),
    ("x" * 201, "201 characters"),
])
def test_model_names_are_safe_labels(name, reason):
    with pytest.raises(ModelError, match=reason):
        System(states=["x"], f=["-x"], outputs=["y"], h=["x"], name=name)
    with pytest.raises(ModelFileError, match=reason):
        loads_model("name = " + _toml_str(name) + "\n" + BASE)


def _toml_str(text: str) -> str:
    return '"' + "".join(c if c.isprintable() and c not in '"\\' else f"\\u{ord(c):04x}" for c in text) + '"'


def test_descriptions_and_units_are_labels_too():
    with pytest.raises(ModelFileError, match="key `description`.*C comment"):
        loads_model('description = "a */ b"\n' + BASE)
    with pytest.raises(ModelFileError, match="key `units.x`.*U\\+001B"):
        loads_model(BASE + '[units]\nx = "m\\u001b"\n')


def test_model_name_with_two_spaces_exports(tmp_path):
    """A CasADi internal error before ("a__b_ekf_cg_init" is not a valid function name)."""
    s = System(states=["x"], f=["-x"], outputs=["y"], h=["x"], name="a  b")
    d = nlobs.design_ekf(s, Q=[[1.0]], R=[[1.0]])
    exp = nlobs.export_c(d, tmp_path)
    assert exp.name == "a_b_ekf"
    with pytest.raises(ValueError, match="single underscores"):
        nlobs.export_c(d, tmp_path, name="a__b")


@pytest.mark.parametrize("name", ["my observer", "e;rm", "ekf\n", "-ekf", "x" * 61, "a,b"])
def test_observer_names_are_restricted(name):
    with pytest.raises(ModelFileError, match="observer's name"):
        loads_model(BASE + f'[observers.{_toml_str(name)}]\nkind = "ekf"\n')


# -- hostile files ---------------------------------------------------------------------------------
def test_utf8_byte_order_mark_is_accepted(tmp_path):
    p = tmp_path / "bom.toml"
    p.write_bytes(b"\xef\xbb\xbf" + BASE.encode())
    assert nlobs.load_model(p).system.states == ("x",)
    assert loads_model("\ufeff" + BASE).system.states == ("x",)


def test_not_utf8_names_the_byte(tmp_path):
    p = tmp_path / "latin.toml"
    p.write_bytes(BASE.replace('"-x"', '"-x" # caf\xe9').encode("latin-1"))
    with pytest.raises(ModelFileError, match=r"latin.toml: the model file is not UTF-8 text \(byte \d+"):
        nlobs.load_model(p)


def test_huge_integer_is_a_model_file_error():
    with pytest.raises(ModelFileError, match="an integer of 5,000 digits: a number in a model must be finite and at most "
                                             "1e300 in magnitude"):
        loads_model(BASE + "[parameters]\nk = " + "9" * 5000 + "\n")
    with pytest.raises(ModelFileError, match="at most 1e300"):
        loads_model(BASE + "[parameters]\nk = " + "9" * 400 + "\n")


def test_deeply_nested_toml_is_a_model_file_error():
    with pytest.raises(ModelFileError, match="nested too deeply"):
        loads_model(BASE + "a = " + "[" * 5000 + "]" * 5000 + "\n")


@pytest.mark.parametrize("size", [200_000, 2_000_000])
def test_huge_text_is_cut_in_the_message(size):
    text = BASE.replace('"-x"', '"' + "x+" * (size // 2) + 'x"')
    with pytest.raises(ModelFileError) as info:
        loads_model(text, path="big.toml")
    msg = str(info.value)
    assert len(msg) < 400, len(msg)
    assert msg.startswith("big.toml, key `dynamics.x`: ") and f"({size + 1} characters)" in msg
    assert msg.endswith(f"the expression is {size + 1} characters long; the limit is 200000 (raise it with "
                        "`nlobs --max-expression N ...` or nlobs.model.set_max_expression(N))")
    assert len(info.value.text) == size + 1  # the attribute keeps the whole text


def test_a_published_model_size_expression_is_accepted_and_means_what_it_says():
    # 100,001 characters: 25,000 terms x_k-like products, beyond Python's parser depth for one chain (~5,000 terms)
    terms = [f"{k % 7 + 1}*x**{k % 3}" for k in range(12_000)]
    text = " + ".join(terms) + " - x"
    assert len(text) > 100_000
    m = loads_model(BASE.replace('"-x"', '"' + text + '"'))
    got = sp.expand(m.system.f[0])
    x = symbol("x")
    ref = sum((k % 7 + 1) * x ** (k % 3) for k in range(12_000)) - x   # the same sum built without the parser
    assert sp.expand(got - ref) == 0


def test_the_limit_can_be_raised_and_a_unary_chain_stays_a_clean_error():
    from nlobs.model import set_max_expression

    text = "+".join(["x"] * 150_001)   # 300,001 characters
    old = set_max_expression(400_000)
    try:
        m = loads_model(BASE.replace('"-x"', '"' + text + '"'))
        assert m.system.f[0] == 150_001 * symbol("x")
    finally:
        set_max_expression(old)
    with pytest.raises(ValueError, match="a positive whole number of characters"):
        set_max_expression(0)
    with pytest.raises(ModelFileError, match="nested"):
        loads_model(BASE.replace('"-x"', '"' + "-(" * 3000 + "x" + ")" * 3000 + '"'))


def test_huge_key_and_name_are_cut_in_the_message():
    with pytest.raises(ModelFileError) as info:
        loads_model(BASE.replace('x = "-x"', "x = \"-x\"\n" + "q" * 100_000 + ' = "1"'))
    assert len(str(info.value)) < 400
    with pytest.raises(ModelError) as info2:
        System(states=["x" * 100_000 + "-"], f=["0"], outputs=["y"], h=["0"])
    assert len(str(info2.value)) < 300


def test_unknown_name_message_lists_at_most_twenty_names():
    names = [f"x{i}" for i in range(500)]
    with pytest.raises(ExpressionError) as info:
        parse_expression("zz", {n: symbol(n) for n in names})
    assert "(500 in all)" in str(info.value) and len(str(info.value)) < 400


# -- symbolic budgets -----------------------------------------------------------------------------------
@pytest.mark.parametrize("text", ["(a + b)**3", "(a + b + c)**5 * (a - c)**2", "(a + b)**2 + (c + 1)**4 * a",
                                  "sin((a + b)**4) + 1", "1/(a + b)**3", "(a*b + c)**6"])
def test_expanded_terms_bounds_what_sympy_makes(text):
    """The bound is checked against the actual expansion (an independent count by SymPy)."""
    syms = {n: symbol(n) for n in "abc"}
    e = parse_expression(text, syms)
    actual = max(len(sp.Add.make_args(node)) for node in sp.preorder_traversal(sp.expand(e)))
    assert expanded_terms(e) >= actual


def test_expanded_terms_of_a_power_of_a_sum_is_the_monomial_count():
    a, b, c = (symbol(n) for n in "abc")
    assert expanded_terms((a + b + c) ** 4) == math.comb(4 + 2, 2) == len(sp.Add.make_args(sp.expand((a + b + c) ** 4)))
    big = parse_expression("(x1 + x2 + u + mu + t)**64", {n: symbol(n) for n in ("x1", "x2", "u", "mu", "t")})
    assert expanded_terms(big) > MAX_TERMS  # C(68, 4) = 814385 terms
    with pytest.raises(SymbolicBudgetError, match="more than 20000 terms"):
        expand(big, what="test")


def test_tree_size_counts_shared_subexpressions_each_time():
    e = symbol("x")
    for _ in range(30):
        e = sp.sin(e) + sp.cos(e)  # a DAG of 91 nodes, a tree of ~3·2^30
    assert tree_size(e) > 200_000
    with pytest.raises(SymbolicBudgetError, match="more than 200000 nodes"):
        System(states=["x"], f=[e], outputs=["y"], h=["x"])


def test_definitions_that_double_their_size_are_refused_not_hung():
    defs = "\n".join(["[definitions]", "d0 = \"sin(x) + cos(x)\""]
                     + [f'd{i} = "sin(d{i - 1}) + cos(d{i - 1})"' for i in range(1, 40)])
    text = BASE.replace('x = "-x"', 'x = "-d39"') .replace("[dynamics]", defs + "\n[dynamics]")
    t0 = time.perf_counter()
    with pytest.raises(SymbolicBudgetError, match="key `definitions.d15`: the expression has more than 200000 nodes"):
        loads_model(text)
    assert time.perf_counter() - t0 < 10


def test_time_budget_stops_sympy_but_not_numeric_work():
    a, b, c, d = (symbol(n) for n in "abcd")
    with pytest.raises(SymbolicBudgetError, match="slow step.*took more than 0.2 s"):
        with symbolic_budget("slow step", seconds=0.2):
            for k in range(2, 60):  # each expansion is cheap, but together they take seconds
                sp.factor(sp.expand((a + b + c + d + 1) ** k))
    with symbolic_budget("numeric step", seconds=0.1):
        t0 = time.perf_counter()
        while time.perf_counter() - t0 < 0.4:  # numeric work is not symbolic time
            np.linalg.eigvals(np.random.default_rng(0).normal(size=(30, 30)))


def test_a_swallowed_budget_error_is_raised_again():
    # SymbolicBudgetError is a ValueError: a broad `except ValueError` in the step must not end the budget
    a, b, c, d = (symbol(n) for n in "abcd")
    swallowed = 0
    t0 = time.perf_counter()
    with pytest.raises(SymbolicBudgetError, match="careless step"):
        with symbolic_budget("careless step", seconds=0.2):
            for k in range(2, 60):
                try:
                    sp.factor(sp.expand((a + b + c + d + 1) ** k))
                except ValueError:
                    swallowed += 1
    assert swallowed >= 1 and time.perf_counter() - t0 < 10


def test_an_inner_time_limit_gives_up_alone_and_the_outer_budget_still_counts():
    a, b, c, d = (symbol(n) for n in "abcd")
    with symbolic_budget("outer step", seconds=30):
        with pytest.raises(SymbolicTimeLimit):
            with symbolic_time_limit(0.2):
                for k in range(2, 60):
                    sp.factor(sp.expand((a + b + c + d + 1) ** k))
        sp.expand((a + b) ** 3)                        # the step goes on after its optional part gave up
    with pytest.raises(SymbolicBudgetError, match="short step"):
        with symbolic_budget("short step", seconds=0.2):
            with symbolic_time_limit(30):              # a generous inner limit does not extend the step's budget
                for k in range(2, 60):
                    sp.factor(sp.expand((a + b + c + d + 1) ** k))


def test_kalman_like_on_a_high_power_stops_within_the_budget(monkeypatch):
    """The repro of issue 10: a state-affine check on a power of a sum of five terms ran for minutes."""
    monkeypatch.setenv("NLOBS_SYMBOLIC_SECONDS", "1")
    s = System(states=["x1", "x2"], f=["x2", "-x1 + 1e-9*(x1 + x2 + u + mu + t)**40"], inputs=["u"], outputs=["y"],
               h=["x1"], params={"mu": 1.0})
    t0 = time.perf_counter()
    with pytest.raises(SymbolicBudgetError, match="design_kalman_like"):
        nlobs.design_kalman_like(s, Q=np.eye(2))
    assert time.perf_counter() - t0 < 15


# -- API --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("fn", [nlobs.design_ekf, nlobs.design_luenberger, nlobs.design_kalman_like, nlobs.design_ukf,
                                nlobs.design_mhe, nlobs.design_gradient])
def test_designs_say_they_want_a_model(fn):
    with pytest.raises(TypeError, match=f"{fn.__name__}: the model must be an nlobs.System.*got str 'pend'"):
        fn("pend", Q=1, R=1)


def test_design_of_a_model_file_points_to_observer_system():
    mf = loads_model(BASE)
    with pytest.raises(TypeError, match="observer_system"):
        nlobs.design_ekf(mf, Q=[[1.0]], R=[[1.0]])
    assert nlobs.design_ekf(mf.observer_system, Q=[[1.0]], R=[[1.0]]).method == "ekf"
    assert nlobs.design_ekf(system=mf.system, Q=[[1.0]], R=[[1.0]]).method == "ekf"  # by keyword too


@pytest.mark.parametrize("text", [None, b"name = 'm'", 3])
def test_loads_model_refuses_what_is_not_text(text):
    # issue 10 (API as a new user): loads_model(None) raised AttributeError from inside the parser
    with pytest.raises(nlobs.ModelFileError, match=r"loads_model takes the text of a model file \(a str\), got "
                                                   + type(text).__name__ + r"; for a file on disk use load_model\(path\)"):
        nlobs.loads_model(text)


def test_the_command_line_raises_the_limit_for_one_command(tmp_path, capsys):
    from nlobs.cli import main
    from nlobs.model import _expr

    path = tmp_path / "big.toml"
    path.write_text(BASE.replace('"-x"', '"' + "+".join(["-x"] * 70_000) + '"'), encoding="utf-8")  # 209,999 characters
    assert main(["analyze", str(path)]) == 1
    assert "the limit is 200000 (raise it with `nlobs --max-expression N" in capsys.readouterr().err
    assert main(["--max-expression", "300000", "analyze", str(path)]) == 0
    assert "locally observable" in capsys.readouterr().out
    assert _expr.MAX_TEXT == 200_000          # restored after the command
