# SPDX-License-Identifier: Apache-2.0
"""Mutation testing on demand: single realistic edits of h4pin's source, each run against a fast
test subset, and the edits no test catches (survivors) printed as a table.

Not part of the test suite nor of CI; nothing else imports it, and it needs no tool beyond the
project's own environment (pytest). Run it from the repository::

    .venv/bin/python scripts/mutate.py --max 40 --seed 1
    .venv/bin/python scripts/mutate.py --modules couplings sidecar --max 10
    .venv/bin/python scripts/mutate.py --list                    # the candidates, counted
    .venv/bin/python scripts/mutate.py --only couplings.py:40:12:drop-term-left

How: the tree is copied once into a temporary folder (the numba caches with it, their files'
times kept, so nothing recompiles); each mutant is one edit of one module of the copy, run with
``python -m pytest -x`` there (the copy first on ``sys.path``, checked), with a timeout, then the
module is put back byte for byte with its time, and any compiled-function cache the run rewrote
is put back too. The working tree is never written; the copy is removed at the end, on Ctrl-C or
SIGTERM as well (``--keep`` keeps it). A mutant is *killed* when the subset fails (a failing test,
or an import or collection error), *survived* when it passes, *timeout* past ``--timeout``.

The operators (applied where the code is, never in docstrings, annotations, f-strings, ``raise``
statements or ``warnings.warn`` messages, nor on a line ending ``# pragma: no mutate``):

* ``cmp-flip``: a comparison negated (``<`` / ``>=``, ``==`` / ``!=``, ``in`` / ``not in``, ...);
  ``cmp-edge``: its boundary moved (``<`` / ``<=``, ``>`` / ``>=``);
* ``arith``: ``+`` / ``-``, ``*`` / ``/`` (also in ``+=``, ``-=``, ...);
* ``drop-term-left`` / ``drop-term-right``: ``a + b`` or ``a - b`` becomes ``a`` (or ``b``);
* ``const``: a number changed (an int n to n + 1, 1 to 0; a float below 1e-3 times 1e4, a
  tolerance loosened; another float times 2; 0.0 to 1.0); ``bool``: ``True`` / ``False``;
* ``boolop``: ``and`` / ``or``; ``not``: ``not x`` becomes ``x``; ``neg``: ``-x`` becomes ``x``;
* ``swap``: the first two names of a tuple unpacking swapped (``a, b = ...``, ``for i, x in``);
* ``drop-stmt``: a one-line statement with an effect (an assignment to an item or attribute, an
  augmented assignment, a call) replaced by ``pass`` (dropping a name's binding is caught by the
  first test that runs the line: not drawn).

Decorators are not mutated either (``frozen=True`` and the like change no number).
"""

from __future__ import annotations

import argparse
import ast
import dataclasses
import json
import os
import random
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
#: The modules mutated by default (short names resolve against these).
MODULES = ("h4pin/elastic/engine.py", "h4pin/elastic/batch.py", "h4pin/elastic/couplings.py",
           "h4pin/elastic/sidecar.py", "h4pin/elastic/mjcf_reader.py", "h4pin/elastic/mechanism.py",
           "h4pin/stiffness/eq30.py", "h4pin/stiffness/matrices.py")
#: The fast test subset of each module (fastest and most discriminating first: pytest -x stops
#: at the first failure). Measured about 40 s (generic engine) and 35 s (eq. 30) a run.
GENERIC_TESTS = ("tests/test_mutants.py", "tests/test_mechanism_fuzz.py", "tests/test_mjcf_mechanism.py",
                 "tests/test_corpus_mjcf.py", "tests/test_beams.py", "tests/test_interop.py",
                 "tests/test_elastic.py", "tests/test_mechanism_compiled.py", "tests/test_corpus.py",
                 "tests/test_mechanism.py")
H4_TESTS = ("tests/test_model.py", "tests/test_stiffness.py", "tests/test_elastic.py", "tests/test_core.py",
            "tests/test_pipeline.py")
#: Survivors judged equivalent: (file name, the source line stripped, operator, old, new) -> why.
#: A survivor that matches is reported as ``equivalent`` with its reason, not as a survivor.
EQUIVALENT = {
    ("batch.py", "if threads == 1 or n <= BLOCK:", "cmp-flip", "==", "!="):
        "threads change no number: the blocks fill disjoint slices whether run serially or on a pool "
        "(the edit only loses the parallelism)",
    ("mjcf_reader.py", "if gap > 1e-9 * length or turn > 1e-9:", "cmp-edge", ">", ">="):
        "a measured gap (of placement or of rotation) exactly equal to its bound: the two comparisons differ on "
        "that one float only",
    ("engine.py", "status: Any = 0", "const", "0", "1"):
        "Modes' default status: every constructor call in h4pin passes the status",
}
#: What the copy leaves out.
SKIP = {".git", ".venv", "venv", ".mypy_cache", ".ruff_cache", ".pytest_cache", "node_modules", "build", "dist"}

CMP_TEXT = {ast.Lt: "<", ast.LtE: "<=", ast.Gt: ">", ast.GtE: ">=", ast.Eq: "==", ast.NotEq: "!=",
            ast.Is: "is", ast.IsNot: "is not", ast.In: "in", ast.NotIn: "not in"}
CMP_FLIP = {"<": ">=", "<=": ">", ">": "<=", ">=": "<", "==": "!=", "!=": "==", "is": "is not",
            "is not": "is", "in": "not in", "not in": "in"}
CMP_EDGE = {"<": "<=", "<=": "<", ">": ">=", ">=": ">"}
CMP_PATTERN = {"<": r"(?<![<>=!])<(?![<=])", "<=": r"<=", ">": r"(?<![<>=-])>(?![>=])", ">=": r"(?<!>)>=",
               "==": r"==", "!=": r"!=", "is": r"\bis\b(?!\s+not\b)", "is not": r"\bis\s+not\b",
               "in": r"(?<!\bnot )\bin\b", "not in": r"\bnot\s+in\b"}
ARITH = {ast.Add: ("+", "-"), ast.Sub: ("-", "+"), ast.Mult: ("*", "/"), ast.Div: ("/", "*")}
ARITH_PATTERN = {"+": r"(?<![+*/=e])\+(?!=)", "-": r"(?<![e=])-(?![=>])", "*": r"(?<!\*)\*(?![*=])",
                 "/": r"(?<!/)/(?![/=])"}


@dataclasses.dataclass(frozen=True)
class Mutant:
    module: str  # path relative to the repository
    line: int
    column: int  # of the edit, in characters, 1-based
    operator: str
    start: int  # byte offsets in the module's source
    end: int
    new: str
    old: str
    nth: int = 1  # the nth mutant of this operator at this place (nested terms)

    @property
    def ident(self) -> str:
        tail = f"~{self.nth}" if self.nth > 1 else ""
        return f"{Path(self.module).name}:{self.line}:{self.column}:{self.operator}{tail}"


# ------------------------------------------------------------------------------ finding mutants
def _excluded_spans(tree: ast.AST) -> list[tuple[int, int, int, int]]:
    """(line, col, end line, end col) of what is never mutated: docstrings, annotations,
    f-strings, raise statements, warnings.warn calls, ``__all__``."""
    spans = []

    def add(node: ast.AST | None) -> None:
        if node is not None and hasattr(node, "lineno"):
            spans.append((node.lineno, node.col_offset, node.end_lineno, node.end_col_offset))

    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(getattr(body[0], "value", None), ast.Constant) \
                    and isinstance(body[0].value.value, str):
                add(body[0])
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            for dec in node.decorator_list:
                add(dec)
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            add(node.returns)
            for a in (*node.args.posonlyargs, *node.args.args, *node.args.kwonlyargs,
                      node.args.vararg, node.args.kwarg):
                if a is not None:
                    add(a.annotation)
        elif isinstance(node, ast.AnnAssign):
            add(node.annotation)
        elif isinstance(node, (ast.JoinedStr, ast.Raise)):
            add(node)
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "warn":
            add(node)
        elif isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == "__all__" for t in node.targets):
            add(node)
    return spans


def _inside(node: ast.AST, spans: list[tuple[int, int, int, int]]) -> bool:
    a = (node.lineno, node.col_offset)
    b = (node.end_lineno, node.end_col_offset)
    return any((s[0], s[1]) <= a and b <= (s[2], s[3]) for s in spans)


class _Source:
    """A module's source with byte offsets of (line, col) positions (ast's columns are UTF-8
    byte offsets)."""

    def __init__(self, text: str):
        self.text = text
        self.data = text.encode()
        self.starts = [0]
        for line in self.data.splitlines(keepends=True):
            self.starts.append(self.starts[-1] + len(line))

    def offset(self, line: int, col: int) -> int:
        return self.starts[line - 1] + col

    def span(self, node: ast.AST) -> tuple[int, int]:
        return self.offset(node.lineno, node.col_offset), self.offset(node.end_lineno, node.end_col_offset)

    def segment(self, a: int, b: int) -> str:
        return self.data[a:b].decode()


def _gap_token(src: _Source, a: int, b: int, pattern: str) -> tuple[int, int] | None:
    """Byte span of the one match of ``pattern`` in the source between offsets a and b."""
    gap = src.segment(a, b)
    hits = list(re.finditer(pattern, gap))
    if len(hits) != 1:
        return None
    prefix = len(gap[:hits[0].start()].encode())
    return a + prefix, a + prefix + len(hits[0].group().encode())


def find_mutants(module: str) -> list[Mutant]:
    """Every mutant of the operators of the module docstring in ``module`` (relative path)."""
    text = (ROOT / module).read_text()
    src = _Source(text)
    tree = ast.parse(text)
    spans = _excluded_spans(tree)
    lines = text.splitlines()
    out: list[Mutant] = []

    def add(node: ast.AST, operator: str, a: int, b: int, new: str) -> None:
        if any(lines[n - 1].rstrip().endswith("# pragma: no mutate") for n in range(node.lineno, node.end_lineno + 1)):
            return
        line = src.data[:a].count(b"\n") + 1
        column = len(src.data[src.starts[line - 1]:a].decode()) + 1
        out.append(Mutant(module, line, column, operator, a, b, new, src.segment(a, b)))

    def is_text(n: ast.AST) -> bool:
        return isinstance(n, ast.JoinedStr) or (isinstance(n, ast.Constant) and isinstance(n.value, (str, bytes)))

    for node in ast.walk(tree):
        if not hasattr(node, "lineno") or _inside(node, spans):
            continue
        if isinstance(node, ast.Compare):
            left = node.left
            for op, right in zip(node.ops, node.comparators, strict=True):
                text_op = CMP_TEXT[type(op)]
                tok = _gap_token(src, src.span(left)[1], src.span(right)[0], CMP_PATTERN[text_op])
                if tok is not None:
                    add(node, "cmp-flip", *tok, CMP_FLIP[text_op])
                    if text_op in CMP_EDGE:
                        add(node, "cmp-edge", *tok, CMP_EDGE[text_op])
                left = right
        elif isinstance(node, ast.BinOp) and type(node.op) in ARITH and not (is_text(node.left) or is_text(node.right)):
            old, new = ARITH[type(node.op)]
            tok = _gap_token(src, src.span(node.left)[1], src.span(node.right)[0], ARITH_PATTERN[old])
            if tok is not None:
                add(node, "arith", *tok, new)
            if isinstance(node.op, (ast.Add, ast.Sub)):
                a, b = src.span(node)
                add(node, "drop-term-left", a, b, f"({src.segment(*src.span(node.left))})")
                if isinstance(node.op, ast.Add):
                    add(node, "drop-term-right", a, b, f"({src.segment(*src.span(node.right))})")
        elif isinstance(node, ast.AugAssign) and type(node.op) in ARITH:
            old, new = ARITH[type(node.op)]
            tok = _gap_token(src, src.span(node.target)[1], src.span(node.value)[0], re.escape(old + "="))
            if tok is not None:
                add(node, "arith", *tok, new + "=")
        elif isinstance(node, ast.BoolOp):
            word = "and" if isinstance(node.op, ast.And) else "or"
            tok = _gap_token(src, src.span(node.values[0])[1], src.span(node.values[1])[0], rf"\b{word}\b")
            if tok is not None:
                add(node, "boolop", *tok, "or" if word == "and" else "and")
        elif isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.Not, ast.USub)):
            if isinstance(node.op, ast.USub) and isinstance(node.operand, ast.Constant):
                continue  # a negative literal: the const operator's
            a, b = src.span(node)
            add(node, "not" if isinstance(node.op, ast.Not) else "neg", a, b,
                f"({src.segment(*src.span(node.operand))})")
        elif isinstance(node, ast.Constant) and type(node.value) in (int, float, bool):
            a, b = src.span(node)
            v = node.value
            if isinstance(v, bool):
                add(node, "bool", a, b, str(not v))
            elif isinstance(v, int):
                add(node, "const", a, b, "0" if v == 1 else str(v + 1))
            elif v == 0.0:
                add(node, "const", a, b, "1.0")
            else:
                add(node, "const", a, b, repr(v * 1e4) if abs(v) < 1e-3 else repr(v * 2))
        elif isinstance(node, (ast.Assign, ast.For)):
            target = node.targets[0] if isinstance(node, ast.Assign) else node.target
            if isinstance(target, ast.Tuple) and len(target.elts) >= 2 \
                    and all(isinstance(e, ast.Name) for e in target.elts[:2]) \
                    and target.elts[0].id != target.elts[1].id:
                (a0, b0), (a1, b1) = src.span(target.elts[0]), src.span(target.elts[1])
                add(node, "swap", a0, b1, f"{src.segment(a1, b1)}{src.segment(b0, a1)}{src.segment(a0, b0)}")
        effect = (isinstance(node, ast.Assign) and all(isinstance(t, (ast.Subscript, ast.Attribute))
                                                       for t in node.targets)) \
            or isinstance(node, ast.AugAssign) or (isinstance(node, ast.Expr) and isinstance(node.value, ast.Call))
        if effect and node.lineno == node.end_lineno:
            a, b = src.span(node)
            add(node, "drop-stmt", a, b, "pass")
    seen: dict[str, int] = {}
    unique = []
    for m in (m for m in out if _compiles(m)):
        seen[m.ident] = seen.get(m.ident, 0) + 1
        unique.append(dataclasses.replace(m, nth=seen[m.ident]))
    return unique


def _line(m: Mutant) -> str:
    """The stripped source line of the mutant (as the working tree has it)."""
    return (ROOT / m.module).read_text().splitlines()[m.line - 1].strip()


def apply(m: Mutant, data: bytes) -> bytes:
    return data[:m.start] + m.new.encode() + data[m.end:]


def _compiles(m: Mutant) -> bool:
    data = (ROOT / m.module).read_bytes()
    try:
        compile(apply(m, data), m.module, "exec")
    except SyntaxError:
        return False
    return True


# ------------------------------------------------------------------------------ running them
#: Where a default module's code went when it was split (h4pin 0.2: h4pin.mechanism).
SPLIT = {"mechanism.py": ("core.py", "assembly.py")}


def _locate(module: str) -> list[str]:
    """``module`` (a path in the repository), or the one file of its name under h4pin/ when it
    has moved (a package reorganised), or the files it was split into; none when there is no such
    file, or several."""
    if (ROOT / module).is_file():
        return [module]
    found = []
    for name in SPLIT.get(Path(module).name, (Path(module).name,)):
        hits = sorted((ROOT / "h4pin").rglob(name))
        if len(hits) == 1:
            found.append(str(hits[0].relative_to(ROOT)))
    return found


def _subset(module: str) -> tuple[str, ...]:
    return H4_TESTS if "/stiffness/" in module else GENERIC_TESTS


def _resolve(names: list[str] | None) -> list[str]:
    known = {m: _locate(m) for m in MODULES}
    if not names:
        for m, where in known.items():
            if not where:
                print(f"mutate: {m} not found (moved?): left out; give it with --modules", file=sys.stderr)
        return [w for ws in known.values() for w in ws]
    out = []
    for n in names:
        hits = [w for m, ws in known.items() for w in ws if n in (m, Path(m).name, Path(m).stem)
                or n in (w, Path(w).name, Path(w).stem)]
        if not hits:
            hits = _locate(n if n.endswith(".py") else f"{n}.py")
        if not hits:
            raise SystemExit(f"mutate: no module {n!r} (known: {', '.join(Path(m).stem for m in MODULES)}, "
                             "or a path in the repository)")
        out += hits
    return out


def _copy_tree(dest: Path) -> None:
    def ignore(folder: str, names: list[str]) -> set[str]:
        return {n for n in names if n in SKIP or n.startswith(".h4pin")}

    shutil.copytree(ROOT, dest, ignore=ignore, symlinks=True)  # copy2: the times kept (numba's cache stamps)


def _caches(tree: Path) -> dict[Path, tuple[int, int]]:
    """numba's cache files of the copy (index and data), with their times and sizes."""
    return {p: (p.stat().st_mtime_ns, p.stat().st_size) for ext in ("*.nbi", "*.nbc")
            for p in (tree / "h4pin").rglob(ext)}


class Runner:
    """The copy, a run of the subset in it, and the putting back of what a run changed."""

    def __init__(self, tree: Path, timeout: float | None):
        self.tree = tree
        self.timeout = timeout
        self.proc: subprocess.Popen | None = None
        self.pristine = tree.parent / "caches"
        self.env = dict(os.environ, PYTHONPATH=str(tree), H4PIN_TEST_WARMUP="0", PYTHONDONTWRITEBYTECODE="1")
        self.env.pop("NUMBA_CACHE_DIR", None)

    def snapshot_caches(self) -> None:
        shutil.rmtree(self.pristine, ignore_errors=True)
        self.cache_state = _caches(self.tree)
        for p in self.cache_state:
            target = self.pristine / p.relative_to(self.tree)
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(p, target)

    def restore_caches(self) -> int:
        """Put back numba's cache files a run rewrote or added; how many."""
        n = 0
        now = _caches(self.tree)
        for p, state in now.items():
            if p not in self.cache_state:
                p.unlink()
                n += 1
            elif state != self.cache_state[p]:
                shutil.copy2(self.pristine / p.relative_to(self.tree), p)
                n += 1
        for p in self.cache_state:
            if p not in now:
                shutil.copy2(self.pristine / p.relative_to(self.tree), p)
                n += 1
        return n

    def check_import(self) -> None:
        out = subprocess.run([sys.executable, "-c", "import h4pin; print(h4pin.__file__)"], cwd=self.tree,
                             env=self.env, capture_output=True, text=True, timeout=300)
        where = Path(out.stdout.strip() or "?").resolve()
        if self.tree.resolve() not in where.parents:
            raise SystemExit(f"mutate: the copy's h4pin is not the one imported ({where}; {out.stderr.strip()})")

    def run(self, tests: list[str], timeout: float | None) -> tuple[str, float, str]:
        """``(killed | survived | timeout, seconds, last lines of the output)``."""
        cmd = [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", "--no-header", *tests]
        t0 = time.monotonic()
        self.proc = subprocess.Popen(cmd, cwd=self.tree, env=self.env, stdout=subprocess.PIPE,
                                     stderr=subprocess.STDOUT, text=True, start_new_session=True)
        try:
            out, _ = self.proc.communicate(timeout=timeout)
            code = self.proc.returncode
        except subprocess.TimeoutExpired:
            self.stop()
            return "timeout", time.monotonic() - t0, ""
        finally:
            self.proc = None
        tail = "\n".join(out.strip().splitlines()[-3:])
        if code == 0:
            return "survived", time.monotonic() - t0, tail
        if code == 5:
            raise SystemExit(f"mutate: no test collected by {' '.join(tests)}")
        return "killed", time.monotonic() - t0, tail

    def stop(self) -> None:
        """End the running subset and its children (its own process group, by its id)."""
        proc = self.proc
        if proc is None or proc.poll() is not None:
            return
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        proc.wait()


def _table(rows: list[dict], title: str) -> str:
    if not rows:
        return f"{title}: none"
    width = max(len(r["id"]) for r in rows)
    lines = [f"{title}:"]
    for r in rows:
        lines.append(f"  {r['id']:<{width}}  {r['old']!r} -> {r['new']!r}  ({r['seconds']:.0f} s)")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--modules", nargs="+", help="modules to mutate (short names or paths; default: "
                   + ", ".join(Path(m).stem for m in MODULES) + ")")
    p.add_argument("--tests", nargs="+", help="test files or node ids to run (default: each module's subset)")
    p.add_argument("--max", type=int, default=40, help="mutants to run at most (default 40), drawn in turn "
                   "from each module")
    p.add_argument("--seed", type=int, default=0, help="seed of the draw (default 0)")
    p.add_argument("--timeout", type=float, default=None, help="seconds a mutant's run may take (default: three "
                   "times the unmutated run, at least that plus 60 s)")
    p.add_argument("--budget", type=float, default=None, help="stop starting mutants after this many seconds")
    p.add_argument("--operators", nargs="+", help="only these operators (cmp-flip, arith, const, swap, ...)")
    p.add_argument("--only", nargs="+", help="run these mutant ids (module:line:column:operator, as --list prints)")
    p.add_argument("--list", action="store_true", help="list the mutants that would be drawn, run nothing")
    p.add_argument("--json", type=Path, help="also write the results there")
    p.add_argument("--keep", action="store_true", help="keep the temporary copy (its path is printed)")
    args = p.parse_args(argv)

    modules = _resolve(args.modules)
    pools = {m: find_mutants(m) for m in modules}
    if args.operators:
        pools = {m: [x for x in v if x.operator in args.operators] for m, v in pools.items()}
    if args.only:
        chosen = [x for v in pools.values() for x in v if x.ident in args.only]
        missing = set(args.only) - {x.ident for x in chosen}
        if missing:
            raise SystemExit(f"mutate: no mutant {sorted(missing)[0]!r} (see --list)")
    else:
        rng = random.Random(args.seed)
        for v in pools.values():
            rng.shuffle(v)
        chosen, turn = [], 0
        while len(chosen) < args.max and any(len(v) > turn for v in pools.values()):
            chosen += [v[turn] for v in pools.values() if len(v) > turn][:args.max - len(chosen)]
            turn += 1
    if args.list:
        for m, v in pools.items():
            print(f"{m}: {len(v)} candidates")
        for x in chosen:
            print(f"  {x.ident:<40} {x.old!r} -> {x.new!r}")
        return 0

    work = Path(tempfile.mkdtemp(prefix="h4pin-mutate-"))
    tree = work / "tree"
    runner = Runner(tree, args.timeout)
    current: dict[str, tuple[Path, bytes, int]] = {}

    def put_back() -> None:
        for path, data, mtime in current.values():
            path.write_bytes(data)
            os.utime(path, ns=(mtime, mtime))
        current.clear()

    def on_signal(signum, frame):  # noqa: ARG001
        raise KeyboardInterrupt

    signal.signal(signal.SIGTERM, on_signal)
    results: list[dict] = []
    code = 0
    try:
        print(f"copying the tree to {tree} ...", flush=True)
        _copy_tree(tree)
        runner.check_import()
        subsets = {m: list(args.tests) if args.tests else list(_subset(m)) for m in modules}
        base: dict[tuple[str, ...], float] = {}
        for subset in {tuple(s) for s in subsets.values()}:
            if not any(subsets[x.module] == list(subset) for x in chosen):
                continue
            print(f"unmutated run of {' '.join(subset)} ...", flush=True)
            status, seconds, tail = runner.run(list(subset), None)
            if status != "survived":
                raise SystemExit(f"mutate: the unmutated tree fails its own tests:\n{tail}")
            base[subset] = seconds
            print(f"  passes in {seconds:.0f} s", flush=True)
        runner.snapshot_caches()
        started = time.monotonic()
        for i, m in enumerate(chosen, 1):
            if args.budget is not None and time.monotonic() - started > args.budget:
                print(f"budget of {args.budget:.0f} s spent: {len(chosen) - i + 1} mutants not run", flush=True)
                break
            path = tree / m.module
            data = path.read_bytes()
            mtime = path.stat().st_mtime_ns
            current[m.module] = (path, data, mtime)
            path.write_bytes(apply(m, data))
            subset = subsets[m.module]
            t_base = base[tuple(subset)]
            timeout = args.timeout or max(3 * t_base, t_base + 60)
            try:
                status, seconds, tail = runner.run(subset, timeout)
            finally:
                put_back()
                rewritten = runner.restore_caches()
            why = EQUIVALENT.get((Path(m.module).name, _line(m), m.operator, m.old, m.new))
            if status == "survived" and why is not None:
                status = "equivalent"
            results.append({"id": m.ident, "module": m.module, "line": m.line, "operator": m.operator, "old": m.old,
                            "new": m.new, "status": status, "seconds": seconds, "caches_restored": rewritten,
                            "why": why if status == "equivalent" else None})
            print(f"[{i}/{len(chosen)}] {status:<8} {m.ident:<40} {m.old!r} -> {m.new!r} ({seconds:.0f} s)",
                  flush=True)
    except KeyboardInterrupt:
        runner.stop()
        print("interrupted", flush=True)
        code = 130
    finally:
        runner.stop()
        put_back()
        if args.keep:
            print(f"copy kept: {tree}")
        else:
            shutil.rmtree(work, ignore_errors=True)
    killed = [r for r in results if r["status"] == "killed"]
    survived = [r for r in results if r["status"] == "survived"]
    timeouts = [r for r in results if r["status"] == "timeout"]
    same = [r for r in results if r["status"] == "equivalent"]
    print(f"\n{len(results)} mutants run: {len(killed)} killed, {len(survived)} survived, {len(same)} known "
          f"equivalent, {len(timeouts)} timed out")
    print(_table(survived, "survivors"))
    if same:
        print(_table(same, "known equivalent (scripts/mutate.py EQUIVALENT)"))
        for r in same:
            print(f"  {r['id']}: {r['why']}")
    if timeouts:
        print(_table(timeouts, "timed out"))
    if args.json:
        args.json.write_text(json.dumps(results, indent=1) + "\n")
    return code


if __name__ == "__main__":
    sys.exit(main())
