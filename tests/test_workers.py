"""The worker protocol (engine/parallel/workers.py): one answer per request, in order, also
when a published version is superseded before a worker gets to it."""
import time

import numpy as np
import pytest

from core_scenes import furnace_box
from ember.engine.integrators.base import Stage
from ember.engine.parallel import workers
from ember.engine.parallel.shared import Publisher


def test_a_version_superseded_before_a_worker_attaches_it_costs_no_answer():
    """Two versions of the same array published back to back: the first segment is unlinked
    at once (every array in it has a newer version), so a worker that reads its install late
    cannot attach it. It must skip it without answering (an answer nobody asked for put the
    pipe out of step: the next item's result went to the wrong request, or, with none
    pending, the reader thread died and the render hung), and still run the next item."""
    if not workers.can_spawn():
        pytest.skip("no worker processes can be started here")
    scene = furnace_box(width=8, height=8, samples=1)
    publisher = Publisher()
    pool = workers.WorkerPool(1)
    try:
        pool.load(scene)
        old = publisher.publish({"study.a": np.zeros(4)})
        new = publisher.publish({"study.a": np.ones(4)})  # unlinks `old`
        pool.install(1, old)
        pool.install(2, new)
        time.sleep(0.5)  # let the worker read both installs with no request pending
        stage = Stage("pixels", 1, film=True, start=0, stop=64)
        result = pool.submit(stage, 0).result(timeout=60)
        assert result[0].shape == (64, 3)
        assert pool.alive()
    finally:
        pool.close(kill=True)
        publisher.release()


def test_cancel_stops_items_in_flight_and_keeps_the_workers():
    """WorkerPool.cancel: items already running stop at their next bounce and items still
    queued are answered without running (both as Cancelled); the same worker processes then
    run the next item, with the scene they had (no new load)."""
    if not workers.can_spawn():
        pytest.skip("no worker processes can be started here")
    from ember.engine.errors import Cancelled

    scene = furnace_box(width=64, height=64, samples=1, batch_size=1 << 20)
    pool = workers.WorkerPool(2)
    try:
        pool.load(scene)
        pids = [w.proc.pid for w in pool.workers]
        big = Stage("pixels", 1, film=True, start=0, stop=1 << 20)  # ~seconds per item
        futures = [pool.submit(big, 0) for _ in range(6)]
        time.sleep(0.5)
        assert pool.cancel(timeout=60)
        outcomes = [type(f.exception()) for f in futures]
        assert outcomes == [Cancelled] * 6
        assert pool.alive() and [w.proc.pid for w in pool.workers] == pids
        small = Stage("pixels", 1, film=True, start=0, stop=64)
        assert pool.submit(small, 0).result(timeout=60)[0].shape == (64, 3)
    finally:
        pool.close(kill=True)


def test_an_abrupt_exit_leaves_no_segment_behind():
    """What render.py's abort (os._exit after a signal) runs first: every segment this process
    created and still owns is unlinked, the ones already released are not touched."""
    import os
    from ember.engine.parallel import shared
    publisher = Publisher()
    name, _ = publisher.publish({"a": np.arange(10.0)})
    pool_counter = shared.create(8)
    released = shared.create(8)
    shared.unlink(released)
    assert {name, pool_counter.name} <= set(shared._OWNED) and released.name not in shared._OWNED
    shared.unlink_all()
    assert not shared._OWNED
    for segment in (name, pool_counter.name):
        assert not os.path.exists(f"/dev/shm/{segment.lstrip('/')}")
    publisher.release()  # nothing left to do, and no error
