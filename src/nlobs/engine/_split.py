"""A very large SX function generated as a chain of parts, so that the C compiler never sees one huge function.

CasADi writes an SX function as one straight-line C function. gcc's optimisation passes are superlinear in the size of
one function: the sample-time update of a 24-state square-root UKF, plant included, 303 thousand instructions, took 91 s
and 1.4 GB at -O1 (full redundancy elimination 26 s, register allocation most of the rest), and its interval run did
not finish compiling within ``nlobs design --run``'s budget. Here the function's instructions, in CasADi's own order,
are cut into parts of about :data:`PART` operations; each part is an SX function of the original inputs and of the
outputs of the earlier parts it reads from (passed whole and read in place), returning the values that later parts or
the outputs read; an MX function calls the parts in order, and a last part copies the outputs into place. (Gathering
the values a part reads into one vector of their own cost a copy of each at every call: the 24-state square-root UKF's
update took 348 µs a call that way, 237 µs reading in place.) Every operation is the original one on the same
operands, so the VM gives the same numbers bit for bit; compiled, the parts are separate C functions, in translation
units of their own (:func:`units`) that gcc compiles apart, two at a time, and links: on that update, 16 units of
about 3 s and 150-380 MB each at -O1 (-O1 as before for code this long, see :data:`nlobs.engine._codegen.BIG_CODE`),
where the one file took 91 s and 1.4 GB.
"""

from __future__ import annotations

import re

import casadi as ca

__all__ = ["split_large", "units", "ABOVE", "PART", "UNIT_LINES"]

#: SX functions with more instructions than this are split (below it one function compiles in seconds at -O1: a
#: 24-state EKF's update, 74,000 instructions, in 3.3 s, where its five units took about 10 s).
ABOVE = 100_000
#: Operations per part.
PART = 5_000


def split_large(fn: ca.Function, above: int | None = None, part: int | None = None) -> ca.Function:
    """`fn` as an MX function that calls parts of about `part` operations (default :data:`PART`) in order, when it is
    an SX function of more than `above` (default :data:`ABOVE`) instructions made of unary and binary operations only;
    else `fn` itself."""
    if not fn.is_a("SXFunction") or fn.n_instructions() <= (ABOVE if above is None else above):
        return fn
    plan = _plan(fn, PART if part is None else part)
    return fn if plan is None else _chain(fn, *plan)


def _plan(fn: ca.Function, part: int) -> tuple[list, list, dict, int] | None:
    """The operations (instruction, op, operands) with the part of each, and the outputs (output, nonzero, value).
    An operand or output value is an instruction index (an operation's result), ("in", input, nonzero) or
    ("c", constant)."""
    work: dict[int, object] = {}
    code, final, piece, count = [], [], 0, 0
    part_of: dict[int, int] = {}
    for k in range(fn.n_instructions()):
        op, i, o = fn.instruction_id(k), fn.instruction_input(k), fn.instruction_output(k)
        if op == ca.OP_INPUT:
            work[o[0]] = ("in", i[0], i[1])
        elif op == ca.OP_CONST:
            work[o[0]] = ("c", fn.instruction_constant(k))
        elif op == ca.OP_OUTPUT:
            final.append((o[0], o[1], work[i[0]]))
        elif len(o) != 1 or len(i) not in (1, 2):   # a call or another multi-output node: not split
            return None
        else:
            if count >= part:
                piece, count = piece + 1, 0
            count += 1
            part_of[k] = piece
            code.append((k, op, [work[j] for j in i]))
            work[o[0]] = k
    return code, final, part_of, piece + 1


def _chain(fn: ca.Function, code: list, final: list, part_of: dict, parts: int) -> ca.Function:
    reads: list[set[int]] = [set() for _ in range(parts)]   # values of earlier parts each part reads
    later: set[int] = set()                                # values read by a later part or an output
    for k, _, args in code:
        for v in args:
            if isinstance(v, int) and part_of[v] != part_of[k]:
                reads[part_of[k]].add(v)
                later.add(v)
    later.update(v for _, _, v in final if isinstance(v, int))
    sx_in = [ca.SX.sym(fn.name_in(i), fn.sparsity_in(i)) for i in range(fn.n_in())]
    nz_in = [[s.nz[j] for j in range(s.nnz())] for s in sx_in]
    mx_in = [ca.MX.sym(fn.name_in(i), fn.sparsity_in(i)) for i in range(fn.n_in())]
    where: dict[int, tuple[int, int]] = {}   # value -> (part, its position in that part's output)
    outs: list[ca.MX] = []
    c = 0
    sizes: list[int] = []
    for p in range(parts):
        # the outputs of the earlier parts it reads, passed whole (read in place: no gathered copy per call)
        sources = sorted({where[v][0] for v in reads[p]})
        cins = {q: ca.SX.sym(f"c{q}", sizes[q]) for q in sources}
        val = {v: cins[where[v][0]][where[v][1]] for v in reads[p]}
        produced = []
        while c < len(code) and part_of[code[c][0]] == p:
            k, op, args = code[c]
            a = [val[v] if isinstance(v, int) else nz_in[v[1]][v[2]] if v[0] == "in" else ca.SX(v[1]) for v in args]
            val[k] = ca.SX.unary(op, a[0]) if len(a) == 1 else ca.SX.binary(op, a[0], a[1])
            if k in later:
                where[k] = (p, len(produced))
                produced.append(k)
            c += 1
        g = ca.Function(f"{fn.name()}_part{p}", [*sx_in, *cins.values()], [ca.vertcat(*[val[v] for v in produced])])
        sizes.append(len(produced))
        outs.append(g.call([*mx_in, *[outs[q] for q in sources]])[0])
    # the outputs gathered by one more part, an SX function of copies (one line of C each): gathered by the MX
    # function instead, each nonzero was a copy loop and a test of its own, which took gcc longer than 15,000 lines
    # of arithmetic (the 24-state square-root UKF's chain: 4.6 s of gcc, now 0.15 s, in a build of 38-40 s of CPU)
    nzs: list[list] = []
    for o in range(fn.n_out()):
        nz: list = [None] * fn.sparsity_out(o).nnz()
        for oo, el, v in final:
            if oo == o:
                nz[el] = v
        if any(v is None for v in nz):   # a nonzero no instruction writes: not the layout expected, not split
            return fn
        nzs.append(nz)
    sources = sorted({where[v][0] for nz in nzs for v in nz if isinstance(v, int)})
    cins = {q: ca.SX.sym(f"c{q}", sizes[q]) for q in sources}
    gathered = [ca.SX(fn.sparsity_out(o), ca.vertcat(*[cins[where[v][0]][where[v][1]] if isinstance(v, int) else
                                                       nz_in[v[1]][v[2]] if v[0] == "in" else ca.SX(v[1]) for v in nz]))
                if nz else ca.SX(fn.sparsity_out(o)) for o, nz in enumerate(nzs)]
    g = ca.Function(f"{fn.name()}_part{parts}", [*sx_in, *cins.values()], gathered)
    res = g.call([*mx_in, *[outs[q] for q in sources]])
    return ca.Function(fn.name(), mx_in, res, fn.name_in(), fn.name_out())


#: Lines of C per translation unit of parts (compiled by a gcc process of its own).
UNIT_LINES = 25_000

_PART = re.compile(r"/\* \w+_part\d+:\((?P<ins>[^)]*)\)->\([^)]*\) \*/\nstatic int (?P<name>casadi_f\d+)\((?P<sig>[^)]*)\) \{\n.*?\n}\n",
                   re.S)
_DEFINITION = re.compile(r"^(?=(?:CASADI_SYMBOL_EXPORT )?[A-Za-z_][\w ]*\** ?\w+\([^;{}]*\) ?\{)(?!static )", re.M)
_HIDDEN = '__attribute__((visibility("hidden"))) '


def units(code: str) -> list[str] | None:
    """The generated C `code` as translation units compiled apart and linked together: the first is `code` with each
    part's body (see :func:`split_large`) replaced by its declaration, the others the parts, a few at a time, each
    after `code`'s preamble (its macros, helpers and constants). None when `code` has no parts. In a part, the values
    carried from earlier parts and its result are read and written without CasADi's null-pointer checks (its caller,
    the chain, always passes them), which leaves the compiler one basic block per part instead of thousands."""
    parts = list(_PART.finditer(code))
    if not parts:
        return None
    first = re.search(r"/\* [\w]+:\([^)]*\)->\([^)]*\) \*/\nstatic int casadi_f\d+\(", code)
    # the preamble of a unit of parts: its functions (helpers, the version queries) local to the unit
    preamble = _DEFINITION.sub("static ", code[:first.start()] if first is not None else "")
    main, bodies, at = [], [], 0
    own = min(m["ins"].count(",") + 1 if m["ins"] else 0 for m in parts)   # the function's inputs (part 0 has no others)
    for m in parts:
        main += [code[at:m.start()], f"{_HIDDEN}int {m['name']}({m['sig']});\n"]
        body = m.group(0).replace(f"static int {m['name']}(", f"{_HIDDEN}int {m['name']}(", 1)
        # the inputs after the function's own: the outputs of earlier parts it reads
        body = re.sub(r"arg\[(\d+)\]\? arg\[\1\]\[(\d+)\] : 0",
                      lambda a: f"arg[{a[1]}][{a[2]}]" if int(a[1]) >= own else a[0], body)
        bodies.append(body.replace("if (res[0]!=0) res[0][", "res[0]["))
        at = m.end()
    main.append(code[at:])
    out, unit, lines = ["".join(main)], [], 0
    for body in bodies:
        unit.append(body)
        lines += body.count("\n")
        if lines >= UNIT_LINES:
            out.append(preamble + "".join(unit))
            unit, lines = [], 0
    if unit:
        out.append(preamble + "".join(unit))
    return out
