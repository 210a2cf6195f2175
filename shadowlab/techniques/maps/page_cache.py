"""Which page each slot of a physical page pool holds, for page caching across the frames of an
animation (the virtual shadow map, :mod:`shadowlab.techniques.maps.virtual_map`; Unreal Engine 5's
virtual shadow maps cache pages the same way: a page stays until the light view or a caster
over it changes)."""
from __future__ import annotations


class PageCache:
    """Which page each physical slot of a pool holds, with the signature of what it was
    rendered from (the light views, the casters over it and their geometry) and when it was
    last used. Kept on the technique across the frames of an animation (``cache=true``): a page
    asked for again with the same signature keeps its slot and its depth, and is not rendered
    again; anything else is a new page."""

    def __init__(self):
        self.pool = None
        self.slots: dict = {}        # page key (face, level, x, y) -> (slot, signature)
        self.last_used: list = []
        self.clock = 0

    def release(self) -> None:
        """Forget every page (what :meth:`shadowlab.techniques.base.Technique.forget` calls)."""
        self.reset(None, 0)

    def state(self) -> tuple:
        """A copy of what the cache holds now (:meth:`restore` puts it back): every render of one
        frame starts from the state the frame began with, so repeated timed renders of a frame
        do the same work (the pages it changed are rendered each time, into the same slots)."""
        return dict(self.slots), list(self.last_used), self.clock

    def restore(self, state: tuple) -> None:
        """Put back a :meth:`state`."""
        slots, last_used, clock = state
        self.slots, self.last_used, self.clock = dict(slots), list(last_used), clock

    def reset(self, pool, size: int) -> None:
        """Empty, for ``pool`` of ``size`` slots (a new pool holds nothing)."""
        self.pool, self.slots, self.last_used, self.clock = pool, {}, [-1] * size, 0

    def assign(self, keys: list, signatures: list) -> tuple[list[int], list[int]]:
        """Slots for the pages ``keys`` (at most the pool's size, distinct), and the indices of
        those that must be rendered: not held, or held with another signature. New pages take
        free slots first, then the least recently used slots of pages not asked for now."""
        self.clock += 1
        slots = [-1] * len(keys)
        fresh = []
        pinned = set()
        for i, (key, sig) in enumerate(zip(keys, signatures)):
            held = self.slots.get(key)
            if held is not None:
                slots[i] = held[0]
                pinned.add(held[0])
                if held[1] != sig:
                    fresh.append(i)
        taken = {slot for slot, _ in self.slots.values()}
        spare = [s for s in range(len(self.last_used)) if s not in taken]
        spare += sorted((s for s in taken if s not in pinned), key=lambda s: self.last_used[s])
        owner = {slot: key for key, (slot, _) in self.slots.items()}
        spare_iter = iter(spare)
        for i, key in enumerate(keys):
            if slots[i] < 0:
                slot = next(spare_iter)
                if slot in owner:
                    del self.slots[owner[slot]]
                slots[i] = slot
                fresh.append(i)
        for i, (key, sig) in enumerate(zip(keys, signatures)):
            self.slots[key] = (slots[i], sig)
            self.last_used[slots[i]] = self.clock
        return slots, sorted(fresh)
