"""Shader node graphs evaluated as Cycles evaluates them: graph.py (the data), registry.py (the
node kinds), program.py (compile once, run per batch), state.py (what nodes read)."""
