"""Repository-level checks: the import layers point one way with no cycle, the README's Python
snippets run as written, documented commands exist, and the docs' links and anchors resolve."""

from __future__ import annotations

import ast
import functools
import re
import subprocess
import sys
from pathlib import Path

import pytest
from in_one_process import run_all

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("raidjax", "trainers", "experiments")
LAYER = {"raidjax": 0, "trainers": 1, "experiments": 2}  # a module may import only its own layer or lower


def _modules() -> dict[str, Path]:
    mods = {}
    for pkg in PACKAGES:
        for path in (ROOT / pkg).rglob("*.py"):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            mods[".".join(parts)] = path
    return mods


def _imports(name: str, path: Path, mods: dict[str, Path]) -> set[str]:
    """Every project module ``name`` imports, anywhere in the file (functions and ``__main__`` too).
    ``from a import b`` counts as importing ``a.b`` when that is a module, else ``a``."""
    is_pkg = path.name == "__init__.py"
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:  # relative import
                anchor = name.split(".") if is_pkg else name.split(".")[:-1]
                anchor = anchor[: len(anchor) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in mods else base for a in node.names]
        else:
            continue
        for t in targets:
            while t and t not in mods:  # "raidjax.types.X" -> "raidjax.types"
                t = t.rpartition(".")[0]
            if t and t != name:
                out.add(t)
    return out


def _find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(n: str) -> list[str] | None:
        state[n] = 1
        stack.append(n)
        for m in sorted(graph.get(n, ())):
            if state.get(m) == 1:
                return stack[stack.index(m):] + [m]
            if m not in state and (found := visit(m)):
                return found
        stack.pop()
        state[n] = 2
        return None

    for n in sorted(graph):
        if n not in state and (found := visit(n)):
            return found
    return None


def test_no_import_cycles_and_layers_point_one_way():
    mods = _modules()
    graph = {name: _imports(name, path, mods) for name, path in mods.items()}
    wrong = [f"{a} -> {b}" for a, deps in graph.items() for b in deps
             if LAYER[b.split(".")[0]] > LAYER[a.split(".")[0]]]
    assert not wrong, f"imports against the layers raidjax -> trainers -> experiments: {wrong}"
    cycle = _find_cycle(graph)
    assert cycle is None, f"import cycle: {' -> '.join(cycle)}"


def test_the_cycle_finder_finds_a_cycle():
    assert _find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert _find_cycle({"a": {"b"}, "b": set()}) is None


SNIPPETS = re.findall(r"```python\n(.*?)```", (ROOT / "README.md").read_text(), re.S)


@pytest.mark.parametrize("code", SNIPPETS, ids=[f"snippet{i}" for i in range(len(SNIPPETS))])
def test_readme_python_snippets_run(code):
    """Every README snippet runs as written (the JaxMARL one, with the [jaxmarl] extra of [dev],
    prints an observation of 112 values and a running game's per-agent results)."""
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]
    if "RaidMultiAgentEnv" in code:
        assert out.stdout.splitlines()[-1].startswith("(112,) [0 0 0] "), out.stdout  # jaxmarl prints on import


def _commands(text: str) -> dict[str, set[str]]:
    """``{module or script: flags}`` of every ``python -m module ...`` and ``python benchmarks/x.py ...``
    command line in ``text``."""
    out: dict[str, set[str]] = {}
    pattern = r"python (-m (?:raidjax|trainers|experiments)\.[\w.]+|benchmarks/\w+\.py)([^`\n|]*)"
    for target, rest in re.findall(pattern, text):
        out.setdefault(target, set()).update(re.findall(r"--[a-z][\w-]*", rest))
    return out


DOCS = [ROOT / "README.md", ROOT / "CONTRIBUTING.md", *sorted((ROOT / "docs").glob("*.md")),
        *sorted((ROOT / "docs" / "results").glob("*.md"))]
DOC_COMMANDS = _commands("".join(p.read_text() for p in DOCS))


@pytest.fixture(scope="module")
def helps() -> dict[str, dict]:
    """Every documented command's ``--help``, run in one fresh process (``in_one_process``)."""
    targets = sorted(DOC_COMMANDS)
    results = run_all([{"target": t, "argv": ["--help"], "cwd": str(ROOT)} for t in targets])
    return dict(zip(targets, results, strict=True))


@pytest.mark.parametrize("module", sorted(DOC_COMMANDS))
def test_documented_commands_exist_with_their_flags(module, helps):
    """Each documented command (module or benchmark script) runs ``--help``, and every flag the docs
    give it is one of its flags (a dry run that does not train or play: no JAX backend starts)."""
    out = helps[module]
    assert out["code"] == 0 and not out["backend"], out["stderr"][-2000:]
    missing = sorted(f for f in DOC_COMMANDS[module] if f not in out["stdout"])
    assert not missing, f"{module} has no flag {missing}"


IMPORT_TO_DIST = {"jax": "jax", "flax": "flax", "numpy": "numpy", "PIL": "pillow", "optax": "optax",
                  "orbax": "orbax-checkpoint", "matplotlib": "matplotlib", "sklearn": "scikit-learn",
                  "tensorboardX": "tensorboardX", "threadpoolctl": "scikit-learn"}  # scikit-learn's own dependency


def _extra(project: dict, name: str) -> set[str]:
    """Distribution names of an extra, self-references (``raidjax[a,b]``) resolved."""
    out = set()
    for req in project["optional-dependencies"][name]:
        dist = re.split(r"[<>=\[ ]", req)[0]
        if dist == "raidjax":
            for sub in re.search(r"\[(.*)\]", req).group(1).split(","):
                out |= _extra(project, sub.strip())
        else:
            out.add(dist)
    return out


def test_each_layer_imports_only_what_its_install_provides():
    """``pip install raidjax`` is enough for the simulator, ``[train]`` adds the trainers and
    ``[experiments]`` the pipelines (tensorboardX is optional: imported under ``try``)."""
    import tomllib

    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    core = {re.split(r"[<>=\[ ]", r)[0] for r in project["dependencies"]}
    allowed = {"raidjax": core, "trainers": core | _extra(project, "train") | _extra(project, "tensorboard"),
               "experiments": core | _extra(project, "experiments")}
    for name in ("trainers.plot", "trainers.runfolder"):  # figures, imported only when drawing: [experiments]
        allowed[name] = allowed["trainers"] | {"matplotlib"}
    for name in ("jaxmarl", "gymnax"):  # each wrapper needs its own extra
        allowed[f"raidjax.wrappers.{name}"] = core | _extra(project, name)
    bad = []
    for name, path in _modules().items():
        layer = allowed.get(name, allowed[name.split(".")[0]])
        for node in ast.walk(ast.parse(path.read_text())):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import) else
                     [node.module] if isinstance(node, ast.ImportFrom) and not node.level else [])
            for n in names:
                top = n.split(".")[0]
                if top in sys.stdlib_module_names or top in PACKAGES:
                    continue
                if IMPORT_TO_DIST.get(top, top) not in layer:
                    bad.append(f"{name} imports {top}")
    assert not bad, bad


def _slug(heading: str) -> str:
    """GitHub's anchor of a Markdown heading: lower case, code marks and punctuation dropped, spaces
    as hyphens."""
    text = re.sub(r"[^\w\- ]", "", heading.replace("`", "").strip().lower())
    return text.replace(" ", "-")


@functools.cache
def _anchors(path: Path) -> frozenset[str]:
    """Every heading anchor of a Markdown file (a repeated heading gets ``-1``, ``-2``, ... as on GitHub)."""
    text = re.sub(r"```.*?```", "", path.read_text(), flags=re.S)
    seen: dict[str, int] = {}
    for heading in re.findall(r"^#+\s+(.*)$", text, flags=re.M):
        s = _slug(heading)
        seen[s] = seen.get(s, -1) + 1
    return frozenset(s if n == 0 else f"{s}-{n}" for s, count in seen.items() for n in range(count + 1))


def broken_links(path: Path) -> list[str]:
    """Relative links of a Markdown file whose file or heading anchor does not exist."""
    text = re.sub(r"```.*?```", "", path.read_text(), flags=re.S)
    bad = []
    for target in re.findall(r"\]\(([^)\s]+)\)", text):
        if re.match(r"[a-z]+:", target):
            continue
        file, _, anchor = target.partition("#")
        dest = (path.parent / file) if file else path
        if not dest.exists():
            bad.append(f"{target}: no such file")
        elif anchor and dest.suffix == ".md" and anchor not in _anchors(dest.resolve()):
            bad.append(f"{target}: no such heading")
    return bad


def test_doc_links_and_anchors_resolve():
    assert _slug("The step on JAX's public API, before and after") == "the-step-on-jaxs-public-api-before-and-after"
    assert len(DOCS) > 10
    assert {str(p.relative_to(ROOT)): b for p in DOCS if (b := broken_links(p))} == {}


def test_a_broken_link_or_anchor_is_caught(tmp_path):
    page = tmp_path / "page.md"
    page.write_text("# Results, `cpu` scale\n\n[ok](#results-cpu-scale) [gone](other.md) [typo](#result)\n")
    assert broken_links(page) == ["other.md: no such file", "#result: no such heading"]
