"""The installed packages use JAX's public API only: no module of ``raidjax``, ``trainers`` or
``experiments`` imports or names a private or internal JAX module (``jax._src``, ``jax.interpreters``,
``jax.extend``, ``jax.core``'s internals, ``jaxlib``), the parts of JAX that change between releases
without notice. ``jax.core.Tracer`` (documented for telling traced values apart) is the one name of
``jax.core`` used."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("raidjax", "trainers", "experiments")
PRIVATE = ("jax._src", "jax.interpreters", "jax.extend", "jax.lib", "jaxlib")
ALLOWED_CORE = {"jax.core.Tracer"}


def _dotted(node: ast.AST) -> str | None:
    """``a.b.c`` for an attribute chain on a name, else ``None``."""
    parts = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    if isinstance(node, ast.Name):
        return ".".join([node.id, *reversed(parts)])
    return None


def private_uses(source: str) -> list[str]:
    """The private JAX names ``source`` imports or reads, as ``line: name``."""
    found = []

    def check(name: str, line: int) -> None:
        private = any(name == p or name.startswith(p + ".") for p in PRIVATE)
        core = name.startswith("jax.core.") and name not in ALLOWED_CORE
        if private or core or name == "jax.core":
            found.append(f"{line}: {name}")

    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            for alias in node.names:
                check(alias.name, node.lineno)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            check(node.module, node.lineno)
            for alias in node.names:
                check(f"{node.module}.{alias.name}", node.lineno)
        elif isinstance(node, ast.Attribute) and not isinstance(getattr(node, "ctx", None), ast.Store):
            name = _dotted(node)
            if name and name.startswith("jax.") and name.count(".") >= 2:  # jax.x.y: a module's member
                check(name, node.lineno)
    return found


def test_no_private_jax_module():
    files = sorted(p for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py"))
    assert len(files) > 50  # the packages were found
    offenders = {str(p.relative_to(ROOT)): found for p in files if (found := private_uses(p.read_text()))}
    assert offenders == {}


@pytest.mark.parametrize("source", [
    "import jax.extend.core as jex_core",
    "from jax.interpreters import batching",
    "from jax._src import xla_bridge",
    "import jax\nx = jax._src.xla_bridge.backends()",
    "import jax\nx = jax.core.Primitive('p')",
])
def test_a_planted_private_import_is_caught(source):
    assert private_uses(source)


def test_public_names_pass():
    assert private_uses("import jax\nfrom jax.custom_batching import custom_vmap\n"
                        "t = isinstance(1, jax.core.Tracer)\ny = jax.numpy.zeros(1)\nz = jax.lax.cond") == []
