"""Mutation testing of one module: do the tests notice a single-point change of the code?

Usage (through ``./dev mutate``, by hand, not in CI)::

    ./dev mutate drivetrain_ctrl/sim/metrics.py --sample 40 --seed 1
    ./dev mutate drivetrain_ctrl.linear.margins --tests tests/unit/test_analysis.py --list

What it does. The module's syntax tree is walked and every *mutation point* is listed: a
comparison flipped at its boundary (``<`` <-> ``<=``, ``>`` <-> ``>=``, ``==`` <-> ``!=``, ``in``
<-> ``not in``, ``is`` <-> ``is not``), an arithmetic operator swapped (``+`` <-> ``-``, ``*`` <->
``/``, ``**``/``//``/``%`` -> ``*``), a unary minus dropped, ``and`` <-> ``or``, an ``if``/
``while``/conditional-expression test negated, a number changed (``0`` -> ``1``, an integer
``n`` -> ``n + 1``, a float ``x`` -> ``2 x``), ``True`` <-> ``False``, ``return EXPR`` ->
``return None`` and ``raise ...`` -> ``pass``. Not mutated: docstrings and other strings,
f-strings, the arguments of ``raise`` (error messages), annotations, ``__all__`` and lines marked
``# pragma: no mutate``. A uniform sample of ``--sample`` points (seeded by ``--seed``) is taken.

Each mutant is applied, one at a time, to a *copy* of the repository in a temporary directory
(the working tree is never touched: other people work in it), and the test files that cover the
module (``--tests``; by default every test file under ``tests/unit`` that imports the module)
are run there with ``PYTHONPATH`` pointing at the copy, stopping at the first failure, with a
timeout. A mutant is *killed* if the tests fail (or do not even import), *survived* if they pass,
*timeout* if they use more than ``--timeout`` seconds of CPU time (by default 3 x the unmutated
run's CPU time + 30 s; a timeout counts as killed in the score: the change was noticed). The
limit is on CPU time, not wall-clock time, so that a machine shared with other work (a test run
three times slower while others compute) does not turn slow survivors into "timeouts"; a
wall-clock limit of 10 x the unmutated run + 300 s only catches a mutant that blocks. The
unmutated copy must pass first.

Survivors are listed as ``file:line: change`` with the original source line. A survivor that is
listed in the equivalents file (``tools/mutation_equivalents.txt``: ``module path | source line,
stripped | change`` per line) is reported as *equivalent* (no test can kill it: the program's
behaviour is the same) and left out of the score:
``score = (killed + timeout) / (mutants - equivalent)``.

The kernels (``drivetrain_ctrl/kernels``) are refused: a change there forces numba to recompile
every kernel (minutes) for every mutant. Only the standard library is used.
"""

from __future__ import annotations

import argparse
import ast
import json
import math
import os
import random
import re
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EQUIVALENTS = ROOT / "tools" / "mutation_equivalents.txt"
#: directories not copied into the sandbox (large, or not needed by the tests)
SKIP_DIRS = {
    ".git",
    ".venv",
    "_build",
    "reports",
    ".mypy_cache",
    ".ruff_cache",
    ".pytest_cache",
    "node_modules",
}
REFUSED = ("drivetrain_ctrl/kernels/",)

_CMP_SWAP: dict[type, type] = {
    ast.Lt: ast.LtE,
    ast.LtE: ast.Lt,
    ast.Gt: ast.GtE,
    ast.GtE: ast.Gt,
    ast.Eq: ast.NotEq,
    ast.NotEq: ast.Eq,
    ast.In: ast.NotIn,
    ast.NotIn: ast.In,
    ast.Is: ast.IsNot,
    ast.IsNot: ast.Is,
}
_BIN_SWAP: dict[type, type] = {
    ast.Add: ast.Sub,
    ast.Sub: ast.Add,
    ast.Mult: ast.Div,
    ast.Div: ast.Mult,
    ast.Pow: ast.Mult,
    ast.FloorDiv: ast.Mult,
    ast.Mod: ast.Mult,
}
_SYMBOL = {
    ast.Lt: "<",
    ast.LtE: "<=",
    ast.Gt: ">",
    ast.GtE: ">=",
    ast.Eq: "==",
    ast.NotEq: "!=",
    ast.In: "in",
    ast.NotIn: "not in",
    ast.Is: "is",
    ast.IsNot: "is not",
    ast.Add: "+",
    ast.Sub: "-",
    ast.Mult: "*",
    ast.Div: "/",
    ast.Pow: "**",
    ast.FloorDiv: "//",
    ast.Mod: "%",
    ast.And: "and",
    ast.Or: "or",
}


@dataclass(frozen=True)
class Point:
    """One mutation point: the ``node``-th node of ``ast.walk`` order, what to do, where."""

    node: int
    kind: str  # cmp, bin, aug, unary, bool, cond, const, return, raise
    sub: int  # index of the operator within a Compare (else 0)
    line: int
    change: str


@dataclass
class Outcome:
    point: Point
    status: str  # killed, survived, timeout
    seconds: float
    source: str
    equivalent: bool = False


def _skipped_nodes(tree: ast.AST) -> set[int]:
    """ids of nodes that are not mutated: strings/f-strings, raise arguments, annotations,
    docstrings, ``__all__``."""
    skip: set[int] = set()

    def mark(n: ast.AST | None) -> None:
        if n is not None:
            skip.update(id(m) for m in ast.walk(n))

    for n in ast.walk(tree):
        if isinstance(n, ast.JoinedStr):
            mark(n)
        elif isinstance(n, ast.Raise):
            mark(n.exc)
            mark(n.cause)
        elif isinstance(n, ast.arg):
            mark(n.annotation)
        elif isinstance(n, ast.AnnAssign):
            mark(n.annotation)
        elif isinstance(n, ast.FunctionDef | ast.AsyncFunctionDef):
            mark(n.returns)
        elif isinstance(n, ast.Assign) and any(
            isinstance(t, ast.Name) and t.id == "__all__" for t in n.targets
        ):
            mark(n)
        elif (
            isinstance(n, ast.Call)
            and isinstance(n.func, ast.Attribute)
            and n.func.attr in ("warn", "debug", "info")
        ):
            mark(n)  # warning / log messages
    return skip


def _number_change(v: int | float) -> int | float:
    if isinstance(v, int):
        return v + 1
    return 1.0 if v == 0 else v * 2.0


def mutation_points(source: str) -> list[Point]:
    """Every mutation point of ``source`` (see the module docstring), in ``ast.walk`` order."""
    tree = ast.parse(source)
    skip = _skipped_nodes(tree)
    lines = source.splitlines()
    points: list[Point] = []
    for k, n in enumerate(ast.walk(tree)):
        if id(n) in skip:
            continue
        line = getattr(n, "lineno", 0)
        if line and "pragma: no mutate" in lines[line - 1]:
            continue
        if isinstance(n, ast.Compare):
            for j, op in enumerate(n.ops):
                new = _CMP_SWAP.get(type(op))
                if new is not None:
                    points.append(
                        Point(k, "cmp", j, line, f"`{_SYMBOL[type(op)]}` -> `{_SYMBOL[new]}`")
                    )
        elif isinstance(n, ast.BinOp | ast.AugAssign):
            new = _BIN_SWAP.get(type(n.op))
            if new is not None:
                kind = "bin" if isinstance(n, ast.BinOp) else "aug"
                a, b = _SYMBOL[type(n.op)], _SYMBOL[new]
                if kind == "aug":
                    a, b = a + "=", b + "="
                points.append(Point(k, kind, 0, line, f"`{a}` -> `{b}`"))
        elif isinstance(n, ast.UnaryOp) and isinstance(n.op, ast.USub):
            points.append(Point(k, "unary", 0, line, "drop unary `-`"))
        elif isinstance(n, ast.BoolOp):
            a = _SYMBOL[type(n.op)]
            b = "or" if a == "and" else "and"
            points.append(Point(k, "bool", 0, line, f"`{a}` -> `{b}`"))
        elif isinstance(n, ast.If | ast.While | ast.IfExp):
            points.append(Point(k, "cond", 0, line, f"negate `{ast.unparse(n.test)}`"))
        elif isinstance(n, ast.Constant) and not isinstance(n.value, str | bytes):
            v = n.value
            if isinstance(v, bool):
                points.append(Point(k, "const", 0, line, f"`{v}` -> `{not v}`"))
            elif isinstance(v, int | float) and not isinstance(v, complex):
                points.append(Point(k, "const", 0, line, f"`{v!r}` -> `{_number_change(v)!r}`"))
        elif isinstance(n, ast.Return) and n.value is not None:
            if not (isinstance(n.value, ast.Constant) and n.value.value is None):
                points.append(Point(k, "return", 0, line, "return None"))
        elif isinstance(n, ast.Raise):
            points.append(Point(k, "raise", 0, line, "remove `raise` (pass)"))
    return points


class _Apply(ast.NodeTransformer):
    def __init__(self, point: Point, target: ast.AST) -> None:
        self.p = point
        self.target = target

    def visit(self, node: ast.AST) -> ast.AST:
        if node is not self.target:
            return super().visit(node)
        p = self.p
        if p.kind == "cmp":
            assert isinstance(node, ast.Compare)
            node.ops[p.sub] = _CMP_SWAP[type(node.ops[p.sub])]()
        elif p.kind in ("bin", "aug"):
            assert isinstance(node, ast.BinOp | ast.AugAssign)
            node.op = _BIN_SWAP[type(node.op)]()
        elif p.kind == "unary":
            assert isinstance(node, ast.UnaryOp)
            return node.operand
        elif p.kind == "bool":
            assert isinstance(node, ast.BoolOp)
            node.op = ast.Or() if isinstance(node.op, ast.And) else ast.And()
        elif p.kind == "cond":
            assert isinstance(node, ast.If | ast.While | ast.IfExp)
            node.test = ast.UnaryOp(op=ast.Not(), operand=node.test)
        elif p.kind == "const":
            assert isinstance(node, ast.Constant)
            v = node.value
            node.value = (not v) if isinstance(v, bool) else _number_change(v)
        elif p.kind == "return":
            assert isinstance(node, ast.Return)
            node.value = ast.Constant(value=None)
        elif p.kind == "raise":
            return ast.Pass()
        return node


def mutate_source(source: str, point: Point) -> str:
    """``source`` with the one change of ``point`` (re-written by ``ast.unparse``)."""
    tree = ast.parse(source)
    nodes = list(ast.walk(tree))
    tree = _Apply(point, nodes[point.node]).visit(tree)
    ast.fix_missing_locations(tree)
    return ast.unparse(tree) + "\n"


def _resolve(module: str) -> Path:
    p = Path(module)
    if not p.suffix:
        p = Path(*module.split(".")).with_suffix(".py")
    p = (ROOT / p).resolve() if not p.is_absolute() else p
    if not p.is_file():
        raise SystemExit(f"mutate: module = {module!r}: no such file {p}")
    rel = p.relative_to(ROOT).as_posix()
    if any(rel.startswith(r) for r in REFUSED):
        raise SystemExit(
            f"mutate: module = {module!r}: the numba kernels are not mutated (every mutant "
            "would recompile every kernel)"
        )
    return p


def default_tests(rel: str) -> list[str]:
    """Test files under tests/unit that import module ``rel`` (a path like a/b/c.py)."""
    dotted = rel.removesuffix(".py").replace("/", ".")
    parent, _, leaf = dotted.rpartition(".")
    pats = [
        re.compile(rf"\b{re.escape(dotted)}\b"),
        re.compile(rf"from\s+{re.escape(parent)}\s+import\s+[^\n]*\b{re.escape(leaf)}\b"),
    ]
    out = []
    for f in sorted((ROOT / "tests" / "unit").glob("test_*.py")):
        text = f.read_text(encoding="utf-8")
        if any(p.search(text) for p in pats):
            out.append(f.relative_to(ROOT).as_posix())
    return out


def _copy_tree(dst: Path, rel: str) -> None:
    """Copy the repository to ``dst``, byte code included (numba's kernel cache, and the other
    modules' .pyc: each mutant then compiles only the mutated module), except the byte code of
    the mutated module ``rel`` itself. A copied .pyc is used only while its source's mtime and
    size match (copytree keeps the mtimes; a mutant is written with a new one)."""

    def ignore(d: str, names: list[str]) -> set[str]:
        return {n for n in names if n in SKIP_DIRS or n.endswith(".egg-info")}

    shutil.copytree(ROOT, dst, ignore=ignore, symlinks=True, dirs_exist_ok=True)
    mod = dst / rel
    for pyc in (mod.parent / "__pycache__").glob(f"{mod.stem}.*.pyc"):
        pyc.unlink()


def _child_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _run_tests(
    sandbox: Path, tests: list[str], timeout: float, cpu_limit: float = 0.0
) -> tuple[str, float, float]:
    """Run ``tests`` in ``sandbox``: (status, wall-clock [s], CPU time [s]). ``cpu_limit`` [s]
    (0: none) is the child's CPU-time limit (RLIMIT_CPU: SIGXCPU, then SIGKILL 5 s later);
    ``timeout`` [s] the wall-clock one. Either ends the run as a "timeout"."""
    env = dict(os.environ)
    env["PYTHONPATH"] = str(sandbox) + os.pathsep + env.get("PYTHONPATH", "")
    env["PYTHONDONTWRITEBYTECODE"] = "1"
    cmd = [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider"]
    cmd += ["-p", "no:xdist", "-m", "not slow", *tests]

    def limit() -> None:
        if cpu_limit > 0:
            soft = math.ceil(cpu_limit)
            resource.setrlimit(resource.RLIMIT_CPU, (soft, soft + 5))

    t0, c0 = time.perf_counter(), _child_cpu()
    try:
        r = subprocess.run(
            cmd,
            cwd=sandbox,
            env=env,
            timeout=timeout,
            capture_output=True,
            text=True,
            preexec_fn=limit,
        )
    except subprocess.TimeoutExpired:
        return "timeout", time.perf_counter() - t0, _child_cpu() - c0
    dt, cpu = time.perf_counter() - t0, _child_cpu() - c0
    if r.returncode in (-signal.SIGXCPU, -signal.SIGKILL) and cpu_limit > 0:
        return "timeout", dt, cpu
    if r.returncode == 5:
        raise SystemExit(f"mutate: no tests collected in {tests}")
    return ("survived" if r.returncode == 0 else "killed"), dt, cpu


def _load_equivalents() -> set[tuple[str, str, str]]:
    out: set[tuple[str, str, str]] = set()
    if not EQUIVALENTS.is_file():
        return out
    for raw in EQUIVALENTS.read_text(encoding="utf-8").splitlines():
        if not raw.strip() or raw.lstrip().startswith("#"):
            continue
        parts = [s.strip() for s in raw.split(" | ")]
        if len(parts) >= 3:
            out.add((parts[0], parts[1], parts[2]))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="./dev mutate", description=__doc__.split("\n")[0])
    ap.add_argument("module", help="a file (drivetrain_ctrl/sim/metrics.py) or a dotted name")
    ap.add_argument("--sample", type=int, default=0, help="mutants to run (0: all)")
    ap.add_argument("--seed", type=int, default=0, help="seed of the sample")
    ap.add_argument("--tests", nargs="+", help="test files (default: unit tests importing it)")
    ap.add_argument(
        "--timeout",
        type=float,
        default=0.0,
        help="CPU time per mutant [s] (0: automatic, 3 x the unmutated run's + 30 s)",
    )
    ap.add_argument(
        "--max-minutes",
        type=float,
        default=0.0,
        help="start no new mutant after this many minutes (0: no limit); the score is then that "
        "of the mutants run",
    )
    ap.add_argument(
        "--lines",
        help="only the points on these source lines, e.g. 195,449 (after --sample: the sampled "
        "points on them; re-run a previous run's survivors with its --sample and --seed)",
    )
    ap.add_argument("--list", action="store_true", help="list the mutation points and stop")
    ap.add_argument("--json", type=Path, help="write the outcomes to this JSON file")
    ap.add_argument("--keep", action="store_true", help="keep the sandbox directory")
    args = ap.parse_args(argv)
    if args.sample < 0:
        ap.error(f"--sample = {args.sample}: must be >= 0")
    if args.timeout < 0:
        ap.error(f"--timeout = {args.timeout}: must be >= 0")
    if args.max_minutes < 0:
        ap.error(f"--max-minutes = {args.max_minutes}: must be >= 0")

    path = _resolve(args.module)
    rel = path.relative_to(ROOT).as_posix()
    source = path.read_text(encoding="utf-8")
    points = mutation_points(source)
    lines = source.splitlines()
    if args.list:
        for p in points:
            print(f"{rel}:{p.line}: {p.change}    | {lines[p.line - 1].strip()}")
        print(f"{len(points)} mutation points")
        return 0
    chosen = points
    if args.sample and args.sample < len(points):
        chosen = sorted(random.Random(args.seed).sample(points, args.sample), key=lambda p: p.node)
    if args.lines:
        try:
            wanted = {int(v) for v in args.lines.split(",") if v.strip()}
        except ValueError:
            ap.error(f"--lines = {args.lines!r}: comma-separated line numbers are needed")
        chosen = [p for p in chosen if p.line in wanted]
        if not chosen:
            ap.error(f"--lines = {args.lines!r}: no (sampled) mutation point on these lines")
    tests = args.tests or default_tests(rel)
    if not tests:
        raise SystemExit(f"mutate: no test file under tests/unit imports {rel}; pass --tests")
    for t in tests:
        if not (ROOT / t).is_file():
            raise SystemExit(f"mutate: --tests: no such file {t!r}")
    equivalents = _load_equivalents()

    tmp = Path(tempfile.mkdtemp(prefix="mutate-"))
    sandbox = tmp / "repo"
    try:
        _copy_tree(sandbox, rel)
        target = sandbox / rel
        print(f"[mutate] {rel}: {len(points)} points, running {len(chosen)} (seed {args.seed})")
        print(f"[mutate] tests: {' '.join(tests)}")
        print(f"[mutate] sandbox: {sandbox}")
        status, base, base_cpu = _run_tests(sandbox, tests, timeout=3600.0)
        if status != "survived":
            raise SystemExit(f"mutate: the tests fail on the unmutated copy ({status}); fix first")
        cpu_limit = args.timeout or 3.0 * base_cpu + 30.0
        wall_limit = max(10.0 * base + 300.0, 2.0 * cpu_limit)
        print(
            f"[mutate] unmutated run: pass in {base:.1f} s ({base_cpu:.1f} s CPU); limit "
            f"{cpu_limit:.0f} s CPU ({wall_limit:.0f} s wall-clock) per mutant"
        )
        outcomes: list[Outcome] = []
        t_start = time.monotonic()
        # SIGTERM (e.g. a kill by pid) stops like Ctrl-C: the mutants run so far are reported
        signal.signal(signal.SIGTERM, signal.default_int_handler)
        try:
            for i, p in enumerate(chosen, 1):
                if args.max_minutes and time.monotonic() - t_start > 60.0 * args.max_minutes:
                    print(f"[mutate] --max-minutes {args.max_minutes:g} reached: stopping")
                    break
                target.write_text(mutate_source(source, p), encoding="utf-8")
                st, sec, _cpu = _run_tests(sandbox, tests, wall_limit, cpu_limit)
                src = lines[p.line - 1].strip()
                eq = st == "survived" and (rel, src, p.change) in equivalents
                outcomes.append(Outcome(p, st, sec, src, eq))
                tag = "equivalent" if eq else st
                print(f"[{i:3d}/{len(chosen)}] {tag:10s} {sec:6.1f} s  {rel}:{p.line}: {p.change}")
                sys.stdout.flush()
        except KeyboardInterrupt:
            print(f"[mutate] interrupted: reporting the {len(outcomes)} mutants run")
        target.write_text(source, encoding="utf-8")
    finally:
        if args.keep:
            print(f"[mutate] sandbox kept: {sandbox}")
        else:
            shutil.rmtree(tmp, ignore_errors=True)

    killed = sum(o.status == "killed" for o in outcomes)
    timeouts = sum(o.status == "timeout" for o in outcomes)
    equiv = sum(o.equivalent for o in outcomes)
    survived = [o for o in outcomes if o.status == "survived" and not o.equivalent]
    n = len(outcomes) - equiv
    score = (killed + timeouts) / n if n else 1.0
    print()
    print(
        f"module {rel}: {len(outcomes)} mutants, killed {killed}, timeout {timeouts}, "
        f"survived {len(survived)}, equivalent {equiv}: score {100 * score:.0f} %"
    )
    if survived:
        print("survivors:")
        for o in survived:
            print(f"  {rel}:{o.point.line}: {o.point.change}    | {o.source}")
    if args.json:
        args.json.write_text(
            json.dumps(
                {
                    "module": rel,
                    "seed": args.seed,
                    "points": len(points),
                    "tests": tests,
                    "score": score,
                    "outcomes": [
                        {**asdict(o.point), **{k: v for k, v in asdict(o).items() if k != "point"}}
                        for o in outcomes
                    ],
                },
                indent=1,
            ),
            encoding="utf-8",
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
