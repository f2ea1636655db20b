"""Ember: a physically based render engine for Blender (NumPy + Embree)."""


def register():
    from .engine.blender import registration
    registration.register()


def unregister():
    from .engine.blender import registration
    registration.unregister()
