"""The installed packages use JAX's public API only: no module of ``raidjax``, ``trainers`` or
``experiments`` imports or names JAX's private modules (``jax._src``, ``jaxlib``), its internal or
unstable ones (``jax.interpreters``, ``jax.extend``, ``jax.lib``) or ``jax.core``'s internals: the
parts of JAX that change between releases without notice. ``jax.core.Tracer`` (documented for
telling traced values apart) is the one name of ``jax.core`` used."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("raidjax", "trainers", "experiments")
PRIVATE = ("jax._src", "jax.interpreters", "jax.extend", "jax.lib", "jaxlib")
ALLOWED_CORE = {"jax.core", "jax.core.Tracer"}
# A module path written as a string (importlib.import_module, __import__, sys.modules[...], getattr);
# the bare distribution name "jaxlib" may be read (its version, from the package metadata).
PRIVATE_TEXT = re.compile(r"^(jax\._src|jax\.interpreters|jax\.extend|jax\.lib)(\.|$)|^jaxlib\.|^_src$")


def _is_private(name: str) -> bool:
    private = any(name == p or name.startswith(p + ".") for p in PRIVATE)
    return private or (name.startswith("jax.core.") and name not in ALLOWED_CORE)


def _dotted(node: ast.AST, aliases: dict[str, str]) -> str | None:
    """``a.b.c`` for an attribute chain on a name, the name replaced by the module it stands for
    (``import jax as j``: ``j.x`` is ``jax.x``), else ``None``."""
    parts = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    if isinstance(node, ast.Name):
        return ".".join([aliases.get(node.id, node.id), *reversed(parts)])
    return None


def _docstrings(tree: ast.AST) -> set[int]:
    """``id``s of the string nodes that are docstrings (prose may name any module)."""
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant):
                found.add(id(first.value))
    return found


def private_uses(source: str) -> list[str]:
    """The private or internal JAX names ``source`` imports, reads, or writes as a module path, as
    ``line: name``."""
    tree = ast.parse(source)
    found = set()
    aliases: dict[str, str] = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if _is_private(alias.name):
                    found.add(f"{node.lineno}: {alias.name}")
                bound = alias.asname or alias.name.split(".")[0]
                aliases[bound] = alias.name if alias.asname else bound
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            for alias in node.names:
                name = f"{node.module}.{alias.name}"
                if _is_private(node.module) or _is_private(name):
                    found.add(f"{node.lineno}: {name}")
                aliases[alias.asname or alias.name] = name
    docstrings = _docstrings(tree)
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute):
            name = _dotted(node, aliases)
            if name and _is_private(name):
                found.add(f"{node.lineno}: {name}")
        elif isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docstrings:
            if PRIVATE_TEXT.match(node.value):
                found.add(f"{node.lineno}: {node.value!r}")
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "getattr":
            # getattr(jax, "interpreters"): an attribute read by its name
            owner = _dotted(node.args[0], aliases) if len(node.args) >= 2 else None
            attr = node.args[1].value if owner and isinstance(node.args[1], ast.Constant) else None
            if isinstance(attr, str) and _is_private(f"{owner}.{attr}"):
                found.add(f"{node.lineno}: {owner}.{attr}")
    return sorted(found)


def test_no_private_jax_module():
    files = sorted(p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py"))
    assert len(files) > 50  # the packages were found
    offenders = {str(p.relative_to(ROOT)): found for p in files if (found := private_uses(p.read_text()))}
    assert offenders == {}


@pytest.mark.parametrize("source", [
    "import jax.extend.core as jex_core",
    "from jax.interpreters import batching",
    "from jax._src import xla_bridge",
    "from jax import _src",
    "import jax\nx = jax._src.xla_bridge.backends()",
    "import jax\nx = jax._src",
    "import jax as j\nx = j.interpreters.batching",
    "import jax\nx = jax.core.Primitive('p')",
    "from jax.core import Primitive",
    "import importlib\nm = importlib.import_module('jax._src.xla_bridge')",
    "import sys\nm = sys.modules['jax._src.xla_bridge']",
    "import jax\nm = getattr(jax, '_src')",
    "import jax\nm = getattr(jax, 'interpreters')",
    "import jax as j\nm = getattr(j, 'extend').core",
    "import jax\nm = getattr(jax.core, 'Primitive')",
])
def test_a_planted_private_use_is_caught(source):
    assert private_uses(source)


def test_public_names_pass():
    source = ("import jax\nimport jax.core\nfrom jax.core import Tracer\nfrom jax.custom_batching import custom_vmap\n"
              "t = isinstance(1, jax.core.Tracer)\ny = jax.numpy.zeros(1)\nz = jax.lax.cond\n"
              "def f():\n    \"\"\"Not jax._src: a docstring may name it.\"\"\"\n")
    assert private_uses(source) == []
