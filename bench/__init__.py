"""Speed against error: Ember's integrators and Cycles on the scenes of bench/scenes.py."""
