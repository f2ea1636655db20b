"""Parallel execution: worker processes (workers.py) and read-only arrays shared with them
(shared.py)."""
