"""The bookkeeping of one render: which work to start, when to stop, the film's passes.

RenderSession.run (engine/session.py) asks the integrator for its stages and hands each to
`Runner.stage`, which submits work items to a backend (worker processes or a thread) and
takes their results in item order.

Film-only stages (the path tracer; the photon integrator's camera pass) run as *units* of
whole passes, one work item each: as many passes as fit in the layout's batch
(`Settings.batch_size` paths, the path tracer's items several batches; an image larger than
that cuts each pass into batch-sized parts instead), at most a worker's share of the
stage's passes (a stage of fewer passes than workers cuts each among them), fewer where a
time limit or an adaptive check comes first. Unit sizes are chosen at run time, yet
the image does not depend on them: a path's random numbers depend on its pixel and sample
only, and the film takes samples pass by pass in pass order. Other stages (photons,
radiance, ppm's pixels) run as the integrator cut them.

The film takes a pass only once all of it has arrived; a stop (cancel, time limit, noise
target) drops the incomplete pass and cancels the items in flight. So an image depends only
on the number of passes done.

Time limit: counted from the session's creation, so the scene build and the worker start-up
use it up too. Each finished unit reports how long it ran; a line through those times,
seconds = a + b x paths (a: the per-item overhead), predicts how long a unit takes. A unit
starts only if it is predicted to end before the limit, after the work already in flight
(spread over the workers). Units start as single passes and double while they fit, up to a
batch, and shrink to single passes as the limit nears; at the limit whatever is still in
flight is cancelled. The first pass is
always completed (an image needs one), and the stages before it (photon maps) always run.
A round of a multi-stage integrator after the first pass (ppm: photons, then pixels) starts
only if the mean time per pass so far predicts it ends before the limit.

Adaptive sampling (engine/adaptive.py): at a check the runner waits until every earlier
pass is in the film, decides the active pixels from it, publishes their list to every
process, and runs the following units over that list only (`Stage.active`).
"""
from __future__ import annotations

import collections
import threading
from dataclasses import dataclass

import numpy as np

from . import adaptive as adaptive_mod
from .errors import Cancelled
from .film import Film
from .integrators.base import Stage

UPDATE_INTERVAL = 0.25
NOISE_INTERVAL = 1.0
MIN_SHARE = 1024  # pixels: a pass is split among the workers only into parts at least this big


@dataclass
class _Unit:
    """A work item: its stage and item number, its film paths if it is a film unit, and the
    clock when it was submitted and when it was seen done."""

    stage: Stage
    item: int
    paths: int
    submitted: float = 0.0
    done: float | None = None


@dataclass
class Progress:
    """What a render has done so far, handed to its on_update callback."""

    samples_done: int
    samples_target: int
    fraction: float
    elapsed: float
    rays: int
    rays_per_second: float
    pass_completed: bool
    noise: float | None
    film: Film
    stage: str = "pixels"  # the stage running now
    time_limit: float = 0.0  # seconds from the session's start (elapsed counts from there too), 0 = none


class Runner:
    def __init__(self, session, on_update, should_stop, clock):
        self.session, self.on_update, self.should_stop, self.clock = session, on_update, should_stop, clock
        self.settings = s = session.scene.settings
        self.t0 = session.t_start
        self.stop = threading.Event()
        self.cancelled = False
        self.ended = False  # stopped before the integrator was done (cancel, time, noise)
        self.stopped_by = ""
        self.passes = 0  # complete passes in the film
        self.pass_clock: list[float] = []  # clock at each pass's completion
        self.open: list = []  # (pixels, L, render passes) of the pass being completed
        self.rays = 0
        self.embree_seconds = 0.0
        self.noise, self.noise_time = None, self.t0
        self.last_update = self.t0
        self.stage_seconds: dict[str, float] = {}
        self.work_t0 = None  # clock when the first item was submitted
        self.timings = collections.deque(maxlen=16)  # (paths, seconds) of the last film units
        self.sent: list[_Unit] = []  # the running stage's items in order
        self.last_passes = 0  # passes of the last unit started (units double while they fit)
        self.limit = s.time_limit
        self.active = None  # adaptive.ActivePixels, or None
        if s.adaptive and session.integrator.adaptive:
            self.active = adaptive_mod.ActivePixels(s, session.layout)
        self.active_list = (0, None)  # (version, border indices) the next units run over
        # Sample indices start at Settings.sample_offset (a part of a split render); passes,
        # checks and the first pass that always runs count from there.
        self.offset = s.sample_offset
        self.next_check = adaptive_mod.first_check(self.active.first) if self.active is not None else 0

    # --- state ------------------------------------------------------------------------------
    def elapsed(self) -> float:
        return self.clock() - self.t0

    def noise_reached(self) -> bool:
        s = self.settings
        return s.noise_target > 0 and self.noise is not None and self.noise <= s.noise_target

    def fraction(self) -> float:
        """Share of the render done: of its paths, or of the time limit if that ends it sooner."""
        f = self.passes / max(self.settings.samples, 1)
        if self.limit > 0:
            f = max(f, self.elapsed() / self.limit)
        return min(f, 1.0)

    def _halt(self, why: str) -> None:
        """Stop now: nothing more is submitted, items in flight are cancelled."""
        if not self.ended:
            self.ended, self.stopped_by = True, why
        self.stop.set()

    def report(self, stage: Stage, pass_completed: bool) -> None:
        if self.on_update is not None:
            elapsed = self.elapsed()
            self.on_update(Progress(self.passes, self.settings.samples, self.fraction(), elapsed, self.rays,
                                    self.rays / max(elapsed, 1e-9), pass_completed, self.noise, self.session.film,
                                    stage.name, self.limit))
        self.last_update = self.clock()

    # --- the time limit -----------------------------------------------------------------
    def _out_of_time(self) -> bool:
        return self.limit > 0 and self.passes >= 1 and self.clock() - self.t0 >= self.limit

    def _service(self):
        """(a, b): a film unit of u paths runs a + b u seconds on one worker (None: no unit
        done yet). A line through the last units' times when their sizes differ enough,
        else their mean time per path."""
        if not self.timings:
            return None
        u, t = (np.array(v, np.float64) for v in zip(*self.timings))
        if u.max() >= 1.5 * u.min():
            b, a = np.polyfit(u, t, 1)
            if a >= 0 and b > 0:
                return a, b
        return 0.0, max(t.sum() / u.sum(), 1e-12)

    def _fits(self, workers: int) -> float:
        """How many paths a new unit may have to end before the limit. Units run in order on
        `workers` workers, so unit i starts when it is submitted or when unit i - workers
        ends, whichever is later (ends are measured for units done, else predicted)."""
        model = self._service()
        if model is None:
            return 0.0
        a, b = model
        now, sent = self.clock(), self.sent
        first = next((i for i, u in enumerate(sent) if u.done is None), len(sent))
        ends = {}
        for i in range(max(0, first - workers), len(sent)):
            u = sent[i]
            if u.done is not None:
                ends[i] = u.done
            else:
                start = max(u.submitted, ends.get(i - workers, u.submitted))
                ends[i] = max(now, start + a + b * u.paths)
        start = max(now, ends.get(len(sent) - workers, now))
        return max(0.0, (self.t0 + self.limit - start - a) / b)

    def round_fits(self) -> bool:
        """Whether a new round (ppm: photons, then a pass) may start before the limit."""
        if self.limit <= 0 or self.passes == 0:
            return True
        t = self.pass_clock
        per_pass = (t[-1] - t[0]) / (len(t) - 1) if len(t) >= 2 else t[0] - (self.work_t0 or self.t0)
        return self.clock() + per_pass - self.t0 <= self.limit

    # --- the film -----------------------------------------------------------------------
    def _film_result(self, stage: Stage, item: int, L: np.ndarray, passes: dict | None = None) -> bool:
        """Buffer an item's radiance by pass and commit every pass it completes; True if one was."""
        layout = self.session.layout
        k = layout.paths(stage, item)
        pixels = layout.pixels(stage)
        n = layout.n_pixels if pixels is None else len(pixels)
        completed = False
        cut = 0
        while cut < len(k):
            end = min(len(k), cut + n - k[cut] % n)  # to the end of k[cut]'s pass
            j = k[cut:end] % n
            self.open.append((layout.pixel[j if pixels is None else pixels[j]], L[cut:end],
                              {name: v[cut:end] for name, v in passes.items()} if passes else None))
            if (k[end - 1] + 1) % n == 0:
                self._commit(int(k[end - 1]) // n)
                completed = True
            cut = end
        return completed

    def _commit(self, p: int) -> None:
        """Pass p is complete: into the film, in pass order."""
        assert p == self.offset + self.passes, "passes must complete in order"
        film, s = self.session.film, self.settings
        half = adaptive_mod.class_a(p)
        for pixel, L, passes in self.open:
            film.add(pixel, L, passes, class_a=half)
        self.open = []
        self.passes = p + 1 - self.offset
        film.end_pass(self.passes)
        self.pass_clock.append(self.clock())
        # The estimate costs a pass over the film: every pass when it can stop the render,
        # else at most once per NOISE_INTERVAL (it is only shown).
        if s.noise_target > 0 or self.clock() - self.noise_time >= NOISE_INTERVAL:
            self.noise, self.noise_time = film.noise(), self.clock()
        # The noise estimate needs a few passes to mean anything.
        if self.passes >= 4 and self.noise_reached():
            self._halt("noise target")

    # --- units of a film-only stage -----------------------------------------------------
    def _units(self, stage: Stage, backend):
        """Generator of the next unit to submit for film-only `stage` (whole passes), or None
        while the next must wait (an adaptive check) or no more may start (time limit)."""
        layout = self.session.layout
        n, batch = layout.n_pixels, layout.batch_size
        p, last = stage.start // n, -(-stage.stop // n)
        workers = max(backend.processes, 1)
        # Every worker gets a share of the passes: an item may hold more than a small render's
        # share (the path tracer's hold several batches).
        first, share = p, -(-(last - p) // workers)
        while p < last:
            if self.active is not None and p - self.offset == self.next_check:
                if self.passes < p - self.offset:
                    yield None  # the check needs every earlier pass in the film
                    continue
                if not self._adapt(backend):
                    return  # every pixel converged
                self.next_check = adaptive_mod.next_check(p - self.offset, len(self.active_list[1]))
            version, pixels = self.active_list
            m_pixels = n if pixels is None else len(pixels)
            # Passes up to the next check run over this list.
            end = last if self.active is None else min(last, self.offset + self.next_check)
            cap = max(1, min(batch // m_pixels, end - p, share))
            if self.active is not None:  # every worker gets part of the passes up to the check
                cap = min(cap, max(1, -(-(end - p) // workers)))
            if self.limit > 0:
                fit = self._fits(workers)
                if not self.timings:
                    cap = 1  # single passes until a unit's time is measured
                elif p > self.offset and fit < min(m_pixels, batch):
                    yield None  # this pass would end after the limit: wait for the units in flight
                    continue
                else:
                    cap = max(1, min(cap, int(fit // m_pixels), 2 * self.last_passes))
                self.last_passes = cap
            part = batch if m_pixels > batch else None  # a pass of several batches
            if part is None and last - first < workers and m_pixels >= workers * MIN_SHARE:
                part = -(-m_pixels // workers)  # fewer passes than workers: a share of each pass
            if part is None:
                yield self._unit(stage, version, p * m_pixels, (p + cap) * m_pixels)
                p += cap
            else:
                for a in range(0, m_pixels, part):
                    yield self._unit(stage, version, p * m_pixels + a, p * m_pixels + min(a + part, m_pixels))
                p += 1

    def _unit(self, stage: Stage, version: int, start: int, stop: int) -> _Unit:
        return _Unit(Stage(stage.name, 1, film=True, start=start, stop=stop, active=version), 0, stop - start)

    def _adapt(self, backend) -> bool:
        """Decide the active pixels from the film (all earlier passes are in it); False when
        none is left."""
        active = self.active.update(self.session.film)
        self.session.integrator.adaptive_counters = (len(active), len(self.active.converged))
        if len(active) == 0:
            return False
        self.session.version += 1
        backend.install(self.session.version, {"layout.active": active.astype(np.int64)}, self.session.publisher)
        self.session.layout.active = (self.session.version, active)
        self.active_list = (self.session.version, active)
        return True

    # --- running a stage ----------------------------------------------------------------
    def stage(self, stage: Stage, backend) -> list | None:
        """Run every item of `stage`; the items' results in order (film stages: []), or None
        if the render stopped before the stage was complete."""
        film_only = stage.film and not stage.publish
        if not stage.film and not self.round_fits():
            self._halt("time limit")
            return None
        if film_only:
            units = self._units(stage, backend)
        else:
            units = iter([_Unit(stage, i, 0) for i in range(stage.items)])
        pending = {}  # future -> sequence number
        self.sent = sent = []
        finished = {}  # sequence number -> result, waiting for its turn (order is fixed)
        results = []
        next_done = 0
        exhausted = False
        if self.work_t0 is None:
            self.work_t0 = self.clock()
        while True:
            if self.should_stop is not None and not self.cancelled and self.should_stop():
                self.cancelled = True
                self._halt("cancel")
            if self._out_of_time():
                self._halt("time limit")
            if self.ended:
                break
            while not exhausted and len(pending) < backend.in_flight:
                unit = next(units, False)
                if unit is False:
                    exhausted = True
                elif unit is None:
                    break
                else:
                    unit.submitted = self.clock()
                    pending[backend.submit(unit.stage, unit.item)] = len(sent)
                    sent.append(unit)
            if not pending:
                if not exhausted and not film_only:
                    continue
                # A film-only stage waiting for throughput with nothing in flight: no unit will fit.
                break
            timeout = UPDATE_INTERVAL
            if self.limit > 0 and self.passes >= 1:  # wake at the limit to cancel what is in flight
                timeout = min(timeout, max(self.t0 + self.limit - self.clock(), 1e-3))
            done = backend.wait(pending, timeout)
            for fut in done:
                seq = pending.pop(fut)
                try:
                    finished[seq] = fut.result()
                except Cancelled:
                    finished[seq] = None
                unit = sent[seq]
                unit.done = self.clock()
                if unit.paths and finished[seq] is not None:
                    self.timings.append((unit.paths, finished[seq][3]))
            completed = False
            while next_done in finished:
                result = finished.pop(next_done)
                if result is None:  # cancelled mid-item: nothing after it is used either
                    self._halt(self.stopped_by or "cancel")
                    break
                unit = sent[next_done]
                data, item_rays, item_embree, _ = result
                if stage.film:
                    passes = data.pop("passes", None) if isinstance(data, dict) else None  # render passes
                    L = data.pop("L") if isinstance(data, dict) else data  # dict: L + arrays to reduce
                    completed |= self._film_result(unit.stage, unit.item, L, passes)
                if stage.publish:
                    results.append(data)
                self.rays += item_rays
                self.embree_seconds += item_embree
                next_done += 1
                if self.ended:
                    break
            # A film stage that also publishes (ppm) completes its pass only once reduced:
            # RenderSession.run reports it then, with the film's overlay up to date.
            pass_completed = completed and not stage.publish
            if pass_completed or self.clock() - self.last_update >= UPDATE_INTERVAL:
                self.report(stage, pass_completed)
            if self.ended:
                break
        self.open = []  # an incomplete pass is dropped
        complete = not self.ended and exhausted and next_done == len(sent)
        if not complete and not self.ended:
            self._halt("time limit")
        return results if complete else None
