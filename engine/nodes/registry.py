"""The node registry: every node kind the evaluator builds, from the modules that implement
them. The coverage table (README) and the compiler read it; a kind not listed here is
reported and falls back (engine/nodes/program.py)."""
from __future__ import annotations

from . import closures, gabor, math, vector, voronoi

REGISTRY = {t.kind: t for module in (closures, gabor, math, vector, voronoi) for t in module.NODES}
