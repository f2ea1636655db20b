"""The node registry: every node kind the evaluator builds, from the modules that implement
them. The coverage table (README) and the compiler read it; a kind not listed here is
reported and falls back (engine/nodes/program.py)."""
from __future__ import annotations

from . import closures, math, textures, vector

REGISTRY = {t.kind: t for module in (closures, math, textures, vector) for t in module.NODES}
