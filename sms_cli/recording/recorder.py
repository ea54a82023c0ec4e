"""MCAP recording of a simulation, viewable in Foxglove; deterministic and finalised on Ctrl-C.

Usage (the simulator's side)::

    rec = McapRecorder(path, mission_text=..., mission_name=..., model_summary=summary,
                       urdf_text=urdf, versions={"sms": "0.1.0", ...}, record_rate_hz=50.0)
    rec.add_transform_tree(links, parents)      # URDF link names; parent "world" for the base
    with rec:
        for each plant step:
            if rec.due(t):                      # optional: skip building the arguments
                rec.write_step(t, transforms=world_poses, scalars={"/attitude": {...}, ...})
            rec.write_event(t, "phase", {"name": "slew"})   # whenever something happens
        rec.finish("completed")                 # or "diverged"; __exit__ does it otherwise

What lands in the file (all times are simulation time: log time = publish time = t in ns, from
t = 0; Foxglove shows them as dates in January 1970):

- ``/tf`` (``foxglove.FrameTransforms``, protobuf, Foxglove's published schema): one message per
  sample holding every link's ``FrameTransform``, the pose of the link in its parent link (URDF
  tree) or in ``world`` for the base, so the URDF drawn by Foxglove's 3D panel moves.
  ``transforms`` rows are world poses ``[x y z qx qy qz qw]`` (m, unit quaternion, scalar last);
  the recorder converts them to parent-relative poses. Values are doubles, written as they are
  (a pose that is not finite is recorded as such).
- ``/robot_description`` (``{data: urdf}``, JSON): the URDF once, at the first recorded time. In
  Foxglove's 3D panel, tick the ``/robot_description`` topic (off by default) and choose
  ``world`` as the display frame. The URDF is also stored as the attachment ``robot.urdf``.
  Meshes referenced by ``package://`` URIs do not resolve from a file; primitives do.
- numeric topics (``scalars``): one protobuf message per topic per sample, with a message type per
  topic (``sms.topic.<path>``, ``sms_cli.recording.schemas``): a ``double`` per number, a packed
  ``repeated double`` per array, exact (no decimal rounding; NaN and infinities kept). Plot them
  in Foxglove as ``/wheels/speed.rw1`` or ``/joints/position.q[2]``; a field name that is not a
  protobuf identifier is sanitised (``rw-1`` → ``rw_1``) and the channel's ``sms.fields`` metadata
  keeps the recorded names.
- ``/events`` (``sms.Event``: t, name, level, detail) and the same text on ``/log``
  (``foxglove.Log``, for Foxglove's Log panel).
- metadata records ``mission`` (name, text, sha256), ``model`` (summary; non-string values as
  JSON), ``versions``, those given as ``metadata`` (``sms simulate`` adds ``sms.timing``: control
  rate, plant step, integrator and at which time a torque is stamped relative to the interval it
  acted over, see ``sms_cli.sim.timing``), and at the end ``run`` (status, steps, samples, events,
  sim times).

Decimation: with ``record_rate_hz = r`` a sample is taken at the first call with
t ≥ t₀ + k/r (k = 1, 2, …; tolerance 1 ppm of the period), where t₀ is the first call's time, so
the mean rate is r whatever the step; calls in between return at once (≈ 0.1 µs). ``None``
records every call.

Interruption: inside ``with rec:`` the recorder handles SIGINT and SIGTERM (each when its
handler is Python's ``default_int_handler``; ``sms`` installs that one for SIGTERM too). Before
anything is recorded a signal raises ``KeyboardInterrupt`` at once. Once recording (and should
that first raise be lost, as in a weakref callback), it is held and raised as
``RecordingInterrupted`` (a ``KeyboardInterrupt``) by the next ``take``, ``select``, ``write_*``
call, after that call's write is complete: the caller's own state is consistent there, so a
loop can catch it and summarise what ran. A signal that arrives after ``finish()`` is raised
by ``__exit__``. ``__exit__`` finishes the file (status ``interrupted``;
``failed`` for any other exception; ``completed`` on a normal exit). Every write goes to the OS
at once and leaves a valid file (see ``mcap_writer``), so even a killed process leaves its
complete chunks readable (``sms inspect`` says the run was killed). A full disk cuts the file
back to its last whole chunk and raises the ``OSError``; the file stays readable. Used without
``with``, the file opens at the first write and ``finish()`` must be called; signals are then
not handled.

Cost: ``benches/bench_recorder.py`` (µs per recorded sample, per-sample and block paths, and
Foxglove's own SDK writer on the same samples).
"""

from __future__ import annotations

import hashlib
import json
import math
import re
import signal
import threading
from pathlib import Path
from collections.abc import Mapping
from typing import Any

import numpy as np

from sms_cli import __version__
from sms_cli.recording import schemas as fs
from sms_cli.recording.encoding import Template, Templates, frame_transform
from sms_cli.recording.frames import RelativePoses
from sms_cli.recording.writer import ChunkedMcapWriter, available_compression

TOPIC_TF = "/tf"
TOPIC_ROBOT_DESCRIPTION = "/robot_description"
TOPIC_EVENTS = "/events"
TOPIC_LOG = "/log"
RESERVED_TOPICS = frozenset({TOPIC_TF, TOPIC_ROBOT_DESCRIPTION, TOPIC_EVENTS, TOPIC_LOG})
WORLD_FRAME = "world"
RUN_STATUSES = ("completed", "diverged", "interrupted", "failed")

_TOPIC_RE = re.compile(r"^(/[A-Za-z0-9_]+)+$")
_PERIOD_TOL = 1e-6  # decimation tolerance, fraction of the period


_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class RecordingInterrupted(KeyboardInterrupt):
    """A SIGINT/SIGTERM raised at a safe point of the recording (see the module docstring)."""


def _jsonable(obj: Any) -> Any:
    """Plain-JSON copy of ``obj``: numpy → Python, non-finite floats → None, keys → str."""
    if isinstance(obj, Mapping):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, np.ndarray):
        return [_jsonable(v) for v in obj.tolist()]
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.generic):
        return _jsonable(obj.item())
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if obj is None or isinstance(obj, (bool, int, str)):
        return obj
    return str(obj)


def _dumps(obj: Any) -> str:
    return json.dumps(_jsonable(obj), sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=False)


def _json_bytes(text: str) -> bytes:
    return json.dumps(text, ensure_ascii=False).encode()


def _time_json(ts: int) -> bytes:
    sec, nsec = divmod(ts, 1_000_000_000)
    return b'{"sec":%d,"nsec":%d}' % (sec, nsec)


def _to_ns(t: float) -> int:
    """Simulation time (s) → integer ns; it must be finite and ≥ 0 (MCAP times are unsigned)."""
    try:
        ts = int(round(float(t) * 1e9))
    except (ValueError, OverflowError, TypeError):
        raise ValueError(f"recorder: simulation time must be a finite number of seconds, got {t!r}") from None
    if ts < 0:
        raise ValueError(f"recorder: simulation time must be ≥ 0 s, got {t!r}")
    return ts


class _ScalarPlan:
    """Encoding plan for one set of numeric topics (the keys of a ``scalars`` dict, in order): per
    topic its fields (name, 0 for a number or the array length), channel and message template."""

    def __init__(self, topics: list[str], fields: list[list[tuple[str, int]]], channels: list[int]):
        self.topics = topics
        self.fields = fields
        self.channels = channels
        self.templates = [_topic_template(spec) for spec in fields]
        self.rows = list(zip(topics, fields))


def _topic_template(spec: list[tuple[str, int]]) -> Template:
    """The message of a numeric topic (``schemas.numeric_topic_descriptor``): field k + 1 is
    spec[k], a double or a packed repeated double."""
    t = Template()
    for number, (_, n) in enumerate(spec, start=1):
        if n:
            t.packed_doubles(number, n)
        else:
            t.double_field(number)
    return t.done()


def world_block_warm_call():
    """The kernel call ``McapRecorder.write_block`` makes on a block of WORLD link poses (its parent-relative
    /tf: ``dynamics.relative_poses``), on one throw-away pose (``sms_cli.sim.compiled.warmup``)."""
    from sms_cli.sim.compiled.warmup import KernelCall

    pose = np.array([[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]])
    return KernelCall("sms_cli.sim.compiled.dynamics:relative_poses", (pose, np.full(1, -1, dtype=np.int64), np.empty((1, 7))),
                      cost=0.3)


class McapRecorder:
    """Records a simulation to an MCAP file: see the module docstring for topics and semantics.

    Parameters: ``path`` (written in place, parents created); ``mission_text`` and
    ``mission_name`` (metadata ``mission``); ``model_summary`` (metadata ``model``); ``urdf_text``
    (``/robot_description`` + attachment, or None); ``versions`` (metadata ``versions``);
    ``record_rate_hz`` (None = every call); ``metadata``: more metadata records (name → {key: text}),
    written with the others at the start (``sms simulate``: ``sms.timing``, ``sms_cli.sim.timing``). Tuning: ``chunk_size`` (uncompressed bytes per chunk),
    ``compression`` ('zstd', 'lz4' or ''; falls back to what is importable).
    """

    def __init__(
        self,
        path: str | Path,
        *,
        mission_text: str,
        mission_name: str,
        model_summary: Mapping[str, Any],
        urdf_text: str | None,
        versions: Mapping[str, str],
        record_rate_hz: float | None = None,
        metadata: Mapping[str, Mapping[str, str]] | None = None,
        chunk_size: int = 256 * 1024,
        compression: str = "zstd",
    ) -> None:
        if record_rate_hz is not None:
            rate = float(record_rate_hz)
            if not (math.isfinite(rate) and rate > 0):
                raise ValueError(f"recorder: record_rate_hz must be a positive number of Hz or None, got {record_rate_hz!r}")
            self._period = 1.0 / rate
        else:
            self._period = 0.0
        self.path = Path(path)
        self.record_rate_hz = record_rate_hz
        self._mission_text = str(mission_text)
        self._mission_name = str(mission_name)
        self._model_summary = dict(model_summary)
        self._urdf_text = urdf_text
        self._versions = {str(k): str(v) for k, v in versions.items()}
        self._metadata = {str(name): {str(k): str(v) for k, v in record.items()} for name, record in (metadata or {}).items()}
        clash = sorted(set(self._metadata) & {"mission", "model", "versions", "run", "repair"})
        if clash:
            raise ValueError(f"recorder: metadata records {clash} are the recorder's own")
        self._chunk_size = int(chunk_size)
        self._compression = available_compression(compression) if compression else ""

        self._file = None
        self._w: ChunkedMcapWriter | None = None
        self.finished = False
        self.status: str | None = None

        # decimation and counters
        self._next_t = -math.inf
        self._t0: float | None = None
        self._t_seen: float | None = None
        self._last_ts = -1
        self._last_event_ts = -1
        self._calls = 0
        self._samples = 0
        self._events = 0
        self._started = False

        # transform tree
        self._links: list[str] | None = None
        self._tf_rel: RelativePoses | None = None
        self._tf_template: Template | None = None
        self._tf_channel = 0

        # numeric topics
        self._topic_fields: dict[str, list[tuple[str, int]]] = {}
        self._topic_channels: dict[str, int] = {}
        self._plans: dict[tuple, _ScalarPlan] = {}
        self._block_templates: dict[tuple, tuple] = {}

        # SIGINT/SIGTERM deferral
        self._busy = False
        self._pending_interrupt = False
        self._old_handlers: dict[int, Any] = {}

    # ------------------------------------------------------------------ set-up
    def add_transform_tree(self, links: list[str], parents: list[str], *, relative: bool = False) -> None:
        """Declare the recorded links (URDF link names) and each one's parent link or ``"world"``.

        Every parent must be ``"world"`` or another listed link, and the tree must be acyclic.
        Rows of ``transforms`` in ``write_step`` follow the order of ``links``; they are world
        poses, converted here to parent-relative ones (≈ 3–10 µs), unless
        ``relative=True`` says the caller already gives each link's pose in its parent. Call once.
        """
        if self._links is not None:
            raise RuntimeError("recorder: add_transform_tree was already called")
        links = [str(x) for x in links]
        parents = [str(x) for x in parents]
        if len(links) != len(parents):
            raise ValueError(f"recorder: {len(links)} links but {len(parents)} parents")
        if not links:
            raise ValueError("recorder: the transform tree needs at least one link")
        if len(set(links)) != len(links):
            dup = sorted({x for x in links if links.count(x) > 1})
            raise ValueError(f"recorder: duplicate link names {dup}")
        if WORLD_FRAME in links or "" in links:
            raise ValueError(f"recorder: a link may not be named {WORLD_FRAME!r} or ''")
        row = {name: i for i, name in enumerate(links)}
        pidx = []
        for link, parent in zip(links, parents):
            if parent == WORLD_FRAME:
                pidx.append(-1)
            elif parent in row:
                pidx.append(row[parent])
            else:
                raise ValueError(f"recorder: parent {parent!r} of link {link!r} is neither {WORLD_FRAME!r} nor a listed link")
        for start in range(len(links)):  # acyclic: every chain reaches the world within n hops
            i, hops = start, 0
            while i >= 0:
                i, hops = pidx[i], hops + 1
                if hops > len(links):
                    raise ValueError(f"recorder: the parent chain of link {links[start]!r} has a cycle")
        self._links = links
        self._tf_rel = None if relative or all(p < 0 for p in pidx) else RelativePoses(pidx)
        tpl = Template()
        for link, parent in zip(links, parents):
            frame_transform(tpl, 1, parent, link)  # FrameTransforms.transforms (field 1), one per link
        self._tf_template = tpl.done()
        if self._w is not None:
            self._busy = True
            try:
                self._register_tf()
            finally:
                self._end_busy()

    def _register_tf(self) -> None:
        w = self._w
        sid = w.register_schema(fs.FRAME_TRANSFORMS_NAME, "protobuf", fs.frame_transforms_descriptor())
        self._tf_channel = w.register_channel(TOPIC_TF, "protobuf", sid)

    def _open(self) -> None:
        if self._w is not None:
            return
        if self.finished:
            raise RuntimeError("recorder: the recording is finished")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file = open(self.path, "wb", buffering=0)  # each record goes to the OS whole, or is cut back
        w = ChunkedMcapWriter(
            self._file,
            chunk_size=self._chunk_size,
            compression=self._compression,
            library=f"sms {__version__} recorder",
        )
        self._w = w
        text = self._mission_text
        w.add_metadata(
            "mission",
            {"name": self._mission_name, "text": text, "sha256": hashlib.sha256(text.encode()).hexdigest()},
        )
        w.add_metadata("model", {str(k): v if isinstance(v, str) else _dumps(v) for k, v in self._model_summary.items()})
        w.add_metadata("versions", self._versions)
        for name, record in self._metadata.items():
            w.add_metadata(name, record)
        if self._urdf_text is not None:
            w.add_attachment("robot.urdf", "application/xml", self._urdf_text.encode())
        if self._links is not None:
            self._register_tf()
        for name, spec in ((TOPIC_EVENTS, fs.EVENT), (TOPIC_LOG, fs.LOG)):
            sid = w.register_schema(spec["title"], "jsonschema", fs.schema_bytes(spec))
            w.register_channel(name, "json", sid)

    def _ensure_open(self) -> None:
        if self._w is None:
            self._busy = True
            try:
                self._open()
            finally:
                self._end_busy()

    def _start(self, ts: int) -> None:
        """First data: publish the URDF at the first recorded time."""
        self._started = True
        if self._urdf_text is not None:
            w = self._w
            sid = w.register_schema(fs.ROBOT_DESCRIPTION["title"], "jsonschema", fs.schema_bytes(fs.ROBOT_DESCRIPTION))
            cid = w.register_channel(TOPIC_ROBOT_DESCRIPTION, "json", sid)
            w.add_message(cid, ts, json.dumps({"data": self._urdf_text}, ensure_ascii=False).encode())

    # ------------------------------------------------------------------ context manager
    def __enter__(self) -> "McapRecorder":
        if threading.current_thread() is threading.main_thread():
            for sig in _SIGNALS:
                if signal.getsignal(sig) is signal.default_int_handler:
                    self._old_handlers[sig] = signal.signal(sig, self._on_signal)
        try:
            self._ensure_open()
        except BaseException as exc:
            self.__exit__(type(exc), exc, exc.__traceback__)
            raise
        return self

    def __exit__(self, exc_type, exc, tb) -> bool:
        try:
            if not self.finished:
                if exc_type is None and not self._pending_interrupt:
                    self.finish("completed")
                elif exc_type is None or issubclass(exc_type, KeyboardInterrupt):
                    self.finish("interrupted")
                else:
                    self.finish("failed", {"exception": exc_type.__name__, "message": str(exc)[:500]})
        except OSError:
            if exc_type is None:
                raise  # else the first error goes on; the file keeps its last whole chunk
        finally:
            for sig, old in self._old_handlers.items():
                if signal.getsignal(sig) == self._on_signal:
                    signal.signal(sig, old)
            self._old_handlers = {}
        pending, self._pending_interrupt = self._pending_interrupt, False
        if exc_type is None and pending:
            raise KeyboardInterrupt
        return False

    def _on_signal(self, signum, frame) -> None:
        self._pending_interrupt = True  # raised by the next recorder call, even if the raise below is lost
        if not (self._busy or self._started):  # nothing recorded yet: stop at once
            raise KeyboardInterrupt

    def _end_busy(self) -> None:
        self._busy = False
        self._check_interrupt()

    def _check_interrupt(self) -> None:
        if self._pending_interrupt and not self.finished:
            self._pending_interrupt = False
            raise RecordingInterrupted

    # ------------------------------------------------------------------ data
    def due(self, t: float) -> bool:
        """Whether ``write_step(t, ...)`` would record a sample (lets the caller skip building it)."""
        return t >= self._next_t

    def take(self, t: float) -> bool:
        """Offer time t for a sample to be written later with ``write_block`` (one ``write_step``
        call's worth of decimation): True reserves it, and the next due time moves on."""
        if self._pending_interrupt:
            self._check_interrupt()
        self._calls += 1
        self._t_seen = t
        if t < self._next_t:
            return False
        self._reserve(t)
        return True

    def _reserve(self, t: float) -> None:
        if self._t0 is None:
            self._t0 = t
        self._next_t = self._next_due(t, self._t0)

    def write_step(
        self,
        t: float,
        *,
        transforms: np.ndarray | None = None,
        scalars: Mapping[str, Mapping[str, Any]] | None = None,
        force: bool = False,
    ) -> bool:
        """Offer the state at simulation time ``t`` (s); record it if a sample is due (or ``force``).

        ``transforms``: (n_links, 7) world poses ``[x y z qx qy qz qw]`` in the order of
        ``add_transform_tree``. ``scalars``: topic → {field: number or 1-D array}. A topic keeps
        its fields (names, array lengths) for the whole run. Returns True when recorded.
        """
        if self._pending_interrupt:
            self._check_interrupt()
        self._calls += 1
        self._t_seen = t
        if t < self._next_t and not force:
            return False
        return self._record(t, transforms, scalars)

    def _record(self, t: float, transforms, scalars) -> bool:
        """One sample, as a block of one (the same encoding as ``write_block``)."""
        if self.finished:
            raise RuntimeError("recorder: write_step after finish()")
        ts = _to_ns(t)
        if ts <= self._last_ts:
            if ts == self._last_ts:
                return False  # already recorded at this time (e.g. a forced final sample)
            raise ValueError(f"recorder: time went backwards: t = {t!r} s after a sample at {self._last_ts / 1e9!r} s")
        if self._w is None:
            self._ensure_open()
        poses = None
        if transforms is not None:
            if self._links is None:
                raise ValueError("recorder: transforms given but add_transform_tree was not called")
            world = np.asarray(transforms, dtype=float)
            n = len(self._links)
            if world.shape != (n, 7):
                raise ValueError(f"recorder: transforms must have shape ({n}, 7) (one [x y z qx qy qz qw] row per link), got {world.shape}")
            poses = (world if self._tf_rel is None else self._tf_rel(world)).reshape(1, -1)
        plan = values = None
        if scalars:
            plan = self._plan_of(scalars)
            values = self._sample_values(plan, scalars)
        self._write_samples(np.array([float(t)]), np.array([ts], dtype=np.int64), poses, plan, values)
        return True

    def _next_due(self, t: float, t0: float) -> float:
        """The earliest time of the sample after one recorded at t (t0: the first sample's time)."""
        if not self._period:
            return -math.inf
        k = math.floor((t - t0) / self._period + _PERIOD_TOL) + 1
        return t0 + (k - _PERIOD_TOL) * self._period

    # ------------------------------------------------------------------ blocks (compiled engine)
    def select(self, times: np.ndarray) -> np.ndarray:
        """Offer successive times at once (``take`` for each): the indices of those reserved for
        a sample, which ``write_block`` then records."""
        self._check_interrupt()
        times = np.asarray(times, dtype=float)
        if times.size == 0:
            return np.zeros(0, dtype=np.intp)
        self._calls += times.size
        self._t_seen = float(times[-1])
        if not self._period:
            picked = np.nonzero(times >= self._next_t)[0]
            if picked.size:
                self._reserve(float(times[picked[-1]]))
            return picked
        i = int(np.searchsorted(times, self._next_t, side="left"))  # first offer at or after the due time
        if i >= times.size:
            return np.zeros(0, dtype=np.intp)
        if self._t0 is None:
            self._t0 = float(times[i])
        # the due time after a sample at each offer (``_next_due``'s arithmetic, elementwise), then the offer it
        # picks: a chain from i, followed on Python ints (``take`` at each offer picks the same ones)
        k = np.floor((times - self._t0) / self._period + _PERIOD_TOL) + 1
        nxt = np.searchsorted(times, self._t0 + (k - _PERIOD_TOL) * self._period, side="left")
        nxt = np.maximum(nxt, np.arange(1, times.size + 1)).tolist()  # at least the next offer
        picked = []
        n = times.size
        while i < n:
            picked.append(i)
            i = nxt[i]
        self._reserve(float(times[picked[-1]]))
        return np.array(picked, dtype=np.intp)

    def count_steps(self, n: int) -> None:
        """Add ``n`` plant steps to ``run.steps``, for a loop that picks its own samples and records
        them with ``write_block`` without offering every step to ``select`` (the two-spacecraft loop)."""
        self._calls += int(n)

    def write_block(self, times: np.ndarray, *, transforms: np.ndarray | None = None,
                    scalars: Mapping[str, Mapping[str, Any]] | None = None, relative: bool = False) -> None:
        """Record n samples at once (the rows ``select`` picked): ``times`` (n,) increasing,
        ``transforms`` (n, n_links, 7) world poses (``relative``: already each link's pose in its
        parent, as /tf carries them), ``scalars`` topic → {field: (n,) or (n, k)}.
        The same messages as n ``write_step(..., force=True)`` calls, encoded and framed in one
        compiled pass (``sms_cli.recording.encoding``)."""
        times = np.asarray(times, dtype=float)
        if times.size == 0:
            return
        if self.finished:
            raise RuntimeError("recorder: write_block after finish()")
        ts = np.rint(times * 1e9).astype(np.int64)
        if not (np.all(np.isfinite(times)) and ts[0] >= 0 and np.all(np.diff(ts) > 0)):
            raise ValueError("recorder: block times must be finite, ≥ 0 and strictly increasing")
        if ts[0] <= self._last_ts:
            raise ValueError(f"recorder: time went backwards: block from {times[0]!r} s after a sample at {self._last_ts / 1e9!r} s")
        if self._w is None:
            self._ensure_open()
        n = times.size
        poses = None if transforms is None else self._block_poses(transforms, n, relative).reshape(n, -1)
        plan = values = None
        if scalars:
            first = {topic: ({name: np.asarray(val)[0] if np.ndim(val) else val for name, val in fields.items()}
                             if isinstance(fields, Mapping) else fields) for topic, fields in scalars.items()}
            plan = self._plan_of(first)
            values = self._block_values(plan, scalars, n)
        self._write_samples(times, ts, poses, plan, values)

    def _plan_of(self, scalars) -> _ScalarPlan:
        """The plan of a set of topics (``scalars``: one sample's or a block's values; built, and
        the new topics registered, at its first use)."""
        plan = self._plans.get(tuple(scalars))
        if plan is None:
            first = {}
            for topic, fields in scalars.items():
                if not isinstance(fields, Mapping):
                    raise ValueError(f"recorder: scalars[{topic!r}] must be a non-empty dict of field → value")
                first[topic] = fields
            self._busy = True
            try:
                plan = self._plan(first)
            finally:
                self._end_busy()
        return plan

    def _write_samples(self, times: np.ndarray, ts: np.ndarray, poses: np.ndarray | None, plan: _ScalarPlan | None,
                       values: np.ndarray | None) -> None:
        """Encode and append n samples (times checked by the caller): /tf from ``poses`` (n, 7 ·
        n_links) parent-relative, then the plan's numeric topics from ``values`` (n, plan values)."""
        n = times.size
        columns = []  # one row of numbers per sample, in template order
        templates = []
        channels = []
        if poses is not None:
            columns.append(poses)
            templates.append(self._tf_template)
            channels.append(self._tf_channel)
        if plan is not None:
            columns.append(values)
            templates += plan.templates
            channels += plan.channels
        if not templates:
            return
        key = (poses is not None, tuple(plan.topics) if plan is not None else ())
        tpl = self._block_templates.get(key)
        if tpl is None:
            tpl = self._block_templates[key] = (Templates(templates), np.array(channels, dtype=np.int64))
        compiled, channel_ids = tpl
        values = np.hstack(columns) if len(columns) > 1 else columns[0]
        self._busy = True
        try:
            if not self._started:
                self._start(int(ts[0]))
            out, end, offsets = compiled.encode(values, channel_ids, self._samples, ts)
            self._append_records(out, end, offsets, ts, channel_ids)
            self._samples += n
            self._last_ts = int(ts[-1])
            if self._t0 is None:
                self._t0 = float(times[0])
            self._next_t = max(self._next_t, self._next_due(float(times[-1]), self._t0))
        finally:
            self._end_busy()

    def _append_records(self, out: np.ndarray, end: int, offsets: np.ndarray, ts: np.ndarray,
                        channel_ids: np.ndarray) -> None:
        """Move framed records (``channel_ids`` (m,) per sample, sample s stamped ``ts[s]``) into
        chunks, flushing full ones, and extend the message indexes. A chunk holds whole samples, so
        a killed run leaves none cut."""
        w = self._w
        m = channel_ids.size
        rec_end = np.append(offsets[1:], end)
        total = offsets.size
        cids = channel_ids.tolist()
        i = 0
        while i < total:
            buf = w.chunk_buffer()
            room = max(w.chunk_size - len(buf), 1)
            j = int(np.searchsorted(rec_end, offsets[i] + room, side="left")) + 1
            j = min(-(-j // m) * m, total)  # up to the end of that record's sample
            base = len(buf) - int(offsets[i])
            buf += out[offsets[i]:rec_end[j - 1]].data
            starts = (offsets[i:j] + base).reshape(-1, m)
            stamps = ts[i // m:j // m]
            if stamps.size == 1:  # one sample (write_step): Python ints are cheaper than arrays
                t = int(stamps[0])
                for cid, start in zip(cids, starts[0].tolist()):
                    w.channel_index(cid).extend((t, start))
            else:
                w.add_index_blocks(cids, stamps, starts)
            if len(buf) >= w.chunk_size:
                w.flush_chunk()
            i = j

    def _block_poses(self, transforms, n: int, relative: bool) -> np.ndarray:
        """Parent-relative poses (n, n_links, 7) of a block of world (or, ``relative``, already relative) poses."""
        if self._links is None:
            raise ValueError("recorder: transforms given but add_transform_tree was not called")
        world = np.asarray(transforms, dtype=float)
        nl = len(self._links)
        if world.shape != (n, nl, 7):
            raise ValueError(f"recorder: block transforms must have shape ({n}, {nl}, 7), got {world.shape}")
        if self._tf_rel is None or relative:
            return world
        from sms_cli.sim.compiled.dynamics import relative_poses

        parents = np.array(self._tf_rel.parents, dtype=np.int64)
        tiled = parents[None, :] + nl * np.arange(n, dtype=np.int64)[:, None]  # row of each parent in the flat block
        tiled[:, parents < 0] = -1
        out = np.empty((n * nl, 7))
        relative_poses(np.ascontiguousarray(world.reshape(n * nl, 7)), tiled.ravel(), out)
        return out.reshape(n, nl, 7)

    def _sample_values(self, plan: _ScalarPlan, scalars) -> np.ndarray:
        """One sample's numeric values (1, n_values) in the plan's order (``write_step``)."""
        vals: list = []
        try:
            for topic, spec in plan.rows:
                fields = scalars[topic]
                if len(fields) != len(spec):
                    raise KeyError
                for name, k in spec:
                    v = fields[name]
                    if k:
                        lst = v.tolist() if isinstance(v, np.ndarray) else list(v)
                        if len(lst) != k:
                            raise KeyError
                        vals.extend(lst)
                    else:
                        vals.append(v)
            return np.array(vals, dtype=float).reshape(1, -1)
        except (KeyError, TypeError, ValueError):
            return self._block_values(plan, {t: {f: np.asarray(v)[None] for f, v in fields.items()} if isinstance(fields, Mapping)
                                             else fields for t, fields in scalars.items()}, 1)  # says what is wrong

    def _block_values(self, plan: _ScalarPlan, scalars, n: int) -> np.ndarray:
        """The numeric topics' values (n, n_values) in the plan's template order."""
        cols = []
        for topic, spec in plan.rows:
            fields = scalars[topic]
            if len(fields) != len(spec) or any(name not in fields for name, _ in spec):
                raise ValueError(f"recorder: the fields of {topic} changed: first {spec}, now {sorted(fields)}")
            for name, k in spec:
                try:
                    col = np.asarray(fields[name], dtype=float)
                except (TypeError, ValueError):
                    raise ValueError(f"recorder: {topic}.{name} is not numeric: {fields[name]!r}") from None
                want = (n,) if k == 0 else (n, k)
                if col.shape != want:
                    raise ValueError(f"recorder: the fields of {topic} changed: {name} must have shape {want} "
                                     f"(first {spec}; 0 = number, n = array length), got {col.shape}")
                cols.append(col.reshape(n, -1))
        return np.hstack(cols)

    def _plan(self, scalars: Mapping[str, Mapping[str, Any]]) -> _ScalarPlan:
        """Validate a new set of topics, register the new ones, and build their templates."""
        topics = list(scalars)
        fields_all = []
        for topic in topics:
            fields = scalars[topic]
            if not isinstance(topic, str) or not _TOPIC_RE.match(topic):
                raise ValueError(f"recorder: topic {topic!r} must look like '/name' or '/group/name' (letters, digits, _)")
            if topic in RESERVED_TOPICS:
                raise ValueError(f"recorder: topic {topic} is reserved for the recorder")
            if not isinstance(fields, Mapping) or not fields:
                raise ValueError(f"recorder: scalars[{topic!r}] must be a non-empty dict of field → value")
            spec = []
            for name, value in fields.items():
                if not isinstance(name, str) or not name:
                    raise ValueError(f"recorder: field names of {topic} must be non-empty strings, got {name!r}")
                arr = np.asarray(value)
                if arr.ndim == 0:
                    spec.append((name, 0))
                elif arr.ndim == 1 and arr.size > 0:
                    spec.append((name, int(arr.size)))
                else:
                    raise ValueError(f"recorder: {topic}.{name} must be a number or a non-empty 1-D array, got shape {arr.shape}")
            known = self._topic_fields.get(topic)
            if known is None:
                self._topic_fields[topic] = spec
                self._register_topic(topic, spec)
            elif known != spec:
                raise ValueError(f"recorder: the fields of {topic} changed: first {known}, now {spec}")
            fields_all.append(spec)
        channels = [self._topic_channels[t] for t in topics]
        plan = _ScalarPlan(topics, fields_all, channels)
        self._plans[tuple(topics)] = plan
        return plan

    def _register_topic(self, topic: str, spec: list[tuple[str, int]]) -> None:
        name, data, meta = fs.numeric_topic_descriptor(topic, spec)
        sid = self._w.register_schema(name, "protobuf", data)
        self._topic_channels[topic] = self._w.register_channel(topic, "protobuf", sid, meta or None)

    def write_event(self, t: float, name: str, detail: Mapping[str, Any] | None = None, *, level: str = "info") -> None:
        """Record an event (phase change, saturation start, divergence…) on ``/events`` and ``/log``.

        ``detail`` is any JSON-able dict (numpy values allowed; non-finite floats become null);
        ``level`` one of unknown, debug, info, warning, error, fatal. Events are not decimated;
        their times must not decrease.
        """
        if self.finished:
            raise RuntimeError("recorder: write_event after finish()")
        if level not in fs.LOG_LEVELS:
            raise ValueError(f"recorder: event level must be one of {list(fs.LOG_LEVELS)}, got {level!r}")
        ts = _to_ns(t)
        if ts < self._last_event_ts:
            raise ValueError(f"recorder: event time went backwards: {t!r} s after an event at {self._last_event_ts / 1e9!r} s")
        detail_json = _dumps(detail or {})
        event = b'{"t":%b,"name":%b,"level":"%b","detail":%b}' % (
            repr(float(t)).encode() if math.isfinite(float(t)) else b"null", json.dumps(str(name), ensure_ascii=False).encode(), level.encode(), detail_json.encode()
        )
        message = str(name) if detail_json == "{}" else f"{name} {detail_json}"
        log = b'{"timestamp":%b,"level":%d,"message":%b,"name":"sms.simulate","file":"","line":0}' % (
            _time_json(ts), fs.LOG_LEVELS[level], json.dumps(message, ensure_ascii=False).encode()
        )
        if self._w is None:
            self._ensure_open()
        self._busy = True
        try:
            if not self._started:
                self._start(ts)
            w = self._w
            w.add_message(w.channel_id(TOPIC_EVENTS), ts, event, self._events & 0xFFFFFFFF)
            w.add_message(w.channel_id(TOPIC_LOG), ts, log, self._events & 0xFFFFFFFF)
            self._events += 1
            self._last_event_ts = ts
            w.maybe_flush()
        finally:
            self._end_busy()

    # ------------------------------------------------------------------ end
    def finish(self, status: str, detail: Mapping[str, Any] | None = None) -> None:
        """Finalise the file: last chunk, metadata ``run``, summary and index. Idempotent.

        ``status``: completed | diverged | interrupted | failed. ``detail`` adds keys to ``run``
        (e.g. the divergence reason).
        """
        if self.finished:
            return
        if status not in RUN_STATUSES:
            raise ValueError(f"recorder: status must be one of {RUN_STATUSES}, got {status!r}")
        self._busy = True
        try:
            if self._w is None:
                self._open()
            w = self._w
            if not self._started:
                self._start(0)
            if w.failed is None:  # after a failed write (a full disk) the open chunk is lost; the rest is tried
                w.flush_chunk()
            run = {
                "status": status,
                "steps": str(self._calls),
                "samples": str(self._samples),
                "events": str(self._events),
                "record_rate_hz": "every step" if self.record_rate_hz is None else repr(float(self.record_rate_hz)),
                "sim_time_s": repr(float(self._t_seen)) if self._t_seen is not None else "0.0",
                "first_sample_s": repr(float(self._t0)) if self._t0 is not None else "",
                "last_sample_s": repr(self._last_ts / 1e9) if self._last_ts >= 0 else "",
            }
            for k, v in (detail or {}).items():
                run[str(k)] = v if isinstance(v, str) else _dumps(v)
            try:
                w.add_metadata("run", run)
                w.finish()
            finally:  # a full disk: the file keeps its last whole chunk and an end marker
                self._file.close()
                self.finished = True
                self.status = status
        finally:
            self._busy = False

    # ------------------------------------------------------------------ introspection
    @property
    def samples(self) -> int:
        """Samples recorded so far."""
        return self._samples

    @property
    def steps(self) -> int:
        """``write_step`` calls so far (recorded or skipped)."""
        return self._calls

    @property
    def sim_time(self) -> float:
        """The last simulation time offered (s; 0 before any)."""
        return float(self._t_seen or 0.0)

    @property
    def on_disk(self) -> tuple[int, float | None]:
        """(messages, last log time in s) in the chunks written so far."""
        if self._w is None:
            return 0, None
        n, t = self._w.on_disk
        return n, None if t is None else t / 1e9


__all__ = ["McapRecorder", "RecordingInterrupted", "RUN_STATUSES", "TOPIC_TF", "TOPIC_ROBOT_DESCRIPTION", "TOPIC_EVENTS", "TOPIC_LOG", "WORLD_FRAME"]
