"""Particle Info (svm/geometry.h svm_node_particle_info) as Cycles evaluates it on an object
that is not a particle instance: Ember reads no particle systems, and every object reads
Cycles' dummy particle (index 0, everything else zero, scene/particles.cpp), whose Random is
the hash of its index, hash_uint2_to_float(0, 0)."""
from __future__ import annotations

import numpy as np

from .base import node, scalar
from .hash import hash_uint2, uint_to_float


def _dummy_random() -> float:
    return float(uint_to_float(hash_uint2(np.zeros(1, np.uint32), np.zeros(1, np.uint32)))[0])


@node("ShaderNodeParticleInfo", "Input")
def particle_info(node, inputs, state):
    zero, vector = scalar(0.0), np.zeros(3)
    return {"Index": zero, "Random": scalar(_dummy_random()), "Age": zero, "Lifetime": zero, "Location": vector,
            "Size": zero, "Velocity": vector, "Angular Velocity": vector}


NODES = (particle_info,)
