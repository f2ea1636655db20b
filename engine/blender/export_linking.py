"""Blender's Light Linking and Shadow Linking -> Cycles' light sets (Mesh.link_sets,
Mesh.link_membership, Lights.links).

An emitter (a light, or an emissive mesh object) may have a receiver collection (the objects
it lights) and a blocker collection (the objects that shadow it). Each object and child
collection in one is included or excluded (its CollectionLightLinking.link_state; a child
collection's state holds for every object in it, at any depth). As the manual has it: only
included objects - the emitter reaches those alone; only excluded ones - everything but them;
both - the included ones minus the excluded.

As Cycles (and Blender's depsgraph light linking) does it, objects are grouped into sets: two
objects are in one set when every linking collection treats them alike; the set of objects in
no linking collection is set 0. An object carries its receiver set and its blocker set; an
emitter carries a 64-bit mask of the receiver sets it lights and one of the blocker sets that
shadow it. At most 64 sets each (Cycles' limit); beyond that, linking is left out with a warning.
"""
from __future__ import annotations

import numpy as np

ALL = np.uint64(0xFFFFFFFFFFFFFFFF)
MAX_SETS = 64
_INCLUDE, _EXCLUDE = 1, 2


def _key(id_block) -> int:
    """The original datablock's pointer (evaluated copies differ from the scene's)."""
    original = getattr(id_block, "original", None)
    return (original if original is not None else id_block).as_pointer()


def _states(collection) -> dict:
    """{original object pointer: _INCLUDE or _EXCLUDE} of a linking collection (excluded wins)."""
    out: dict = {}

    def put(ob, state):
        key = _key(ob)
        out[key] = max(out.get(key, 0), state)

    def walk(coll, state):
        for ob in coll.all_objects:
            put(ob, state)

    # collection_objects and collection_children hold the link states of objects and children
    # in the order of collection.objects and collection.children.
    for ob, entry in zip(collection.objects, collection.collection_objects):
        put(ob, _EXCLUDE if entry.light_linking.link_state == "EXCLUDE" else _INCLUDE)
    for child, entry in zip(collection.children, collection.collection_children):
        walk(child, _EXCLUDE if entry.light_linking.link_state == "EXCLUDE" else _INCLUDE)
    return out


class _Sets:
    """The sets of one kind of linking (receiver or blocker) over its collections."""

    def __init__(self, collections: list):
        self.keys = []  # collection pointers, in order
        states = []
        for c in collections:
            key = _key(c)
            if key not in self.keys:
                self.keys.append(key)
                states.append(_states(c))
        self.has_include = [any(v == _INCLUDE for v in s.values()) for s in states]
        objects = sorted({o for s in states for o in s})
        signature = {o: tuple(s.get(o, 0) for s in states) for o in objects}
        default = (0,) * len(states)
        self.signatures = [default] + sorted(set(signature.values()) - {default})
        index = {sig: i for i, sig in enumerate(self.signatures)}
        self.set_of = {o: index[sig] for o, sig in signature.items()}

    @property
    def fits(self) -> bool:
        return len(self.signatures) <= MAX_SETS

    def mask(self, collection) -> np.uint64:
        """The sets an emitter with this linking collection (or None) reaches."""
        if collection is None:
            return ALL
        c = self.keys.index(_key(collection))
        bits = 0
        for s, sig in enumerate(self.signatures):
            state = sig[c]
            if state == _INCLUDE or (state == 0 and not self.has_include[c]):
                bits |= 1 << s
        return np.uint64(bits)


class LinkSets:
    """The scene's light and shadow linking; `active` False when no emitter uses any."""

    def __init__(self, scene, warn):
        emitters = [ob for ob in scene.objects
                    if getattr(ob, "light_linking", None) is not None
                    and (ob.light_linking.receiver_collection is not None
                         or ob.light_linking.blocker_collection is not None)]
        self.receivers = _Sets([ob.light_linking.receiver_collection for ob in emitters
                                if ob.light_linking.receiver_collection is not None])
        self.blockers = _Sets([ob.light_linking.blocker_collection for ob in emitters
                               if ob.light_linking.blocker_collection is not None])
        self.active = bool(emitters)
        if self.active and not (self.receivers.fits and self.blockers.fits):
            warn(f"Light linking needs more than {MAX_SETS} sets of objects; it is ignored.")
            self.active = False

    def of_object(self, ob) -> tuple:
        """(receiver set, blocker set, receiver mask, blocker mask) of an object (its masks: as
        an emitter, for emissive meshes)."""
        if not self.active:
            return 0, 0, ALL, ALL
        key = _key(ob)
        return (self.receivers.set_of.get(key, 0), self.blockers.set_of.get(key, 0)) + self.masks(ob)

    def masks(self, ob) -> tuple:
        """(receiver mask, blocker mask) of an emitter: the sets it lights, the sets that shadow it."""
        if not self.active:
            return ALL, ALL
        links = ob.light_linking
        return self.receivers.mask(links.receiver_collection), self.blockers.mask(links.blocker_collection)
