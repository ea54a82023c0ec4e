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

- ``/tf`` (``foxglove.FrameTransform``, JSON): one message per link per sample, the pose of the
  link in its parent link (URDF tree) or in ``world`` for the base, so the URDF drawn by
  Foxglove's 3D panel moves. ``transforms`` rows are world poses ``[x y z qx qy qz qw]`` (m, unit
  quaternion, scalar last); the recorder converts them to parent-relative poses. A link whose
  pose is not finite is left out of that sample (the schema has no "unknown").
- ``/robot_description`` (``{data: urdf}``): the URDF once, at the first recorded time. In
  Foxglove's 3D panel, tick the ``/robot_description`` topic (off by default) and choose
  ``world`` as the display frame. The URDF is also stored as the attachment ``robot.urdf``.
  Meshes referenced by ``package://`` URIs do not resolve from a file; primitives do.
- numeric topics (``scalars``): one JSON object per topic per sample, with a schema per topic
  (``sms.<topic with dots>``). Plot them in Foxglove as ``/wheels/speed.rw1`` or
  ``/joints/position.q[2]`` (field names made of letters, digits and _ are the easiest to
  address there; any non-empty name is accepted). Fields are numbers or fixed-length arrays; a non-finite value is
  written as ``null``. Numbers are printed with 12 significant digits (``%.12g``).
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

Cost (``benches/bench_recorder.py``): a recorded sample of 15 links + 8 topics ≈ 50 µs, a
skipped call ≈ 0.1 µs, ≈ 1.6 MB per 1000 such samples (zstd level 1).
"""

from __future__ import annotations

import hashlib
import json
import math
import re
import signal
import threading
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from sms_cli import __version__
from sms_cli.sim import foxglove_schemas as fs
from sms_cli.sim.frames import RelativePoses
from sms_cli.sim.mcap_block import Templates, encode_records
from sms_cli.sim.mcap_writer import MESSAGE_FIXED, MESSAGE_HEADER, ChunkedMcapWriter, available_compression

TOPIC_TF = "/tf"
TOPIC_ROBOT_DESCRIPTION = "/robot_description"
TOPIC_EVENTS = "/events"
TOPIC_LOG = "/log"
RESERVED_TOPICS = frozenset({TOPIC_TF, TOPIC_ROBOT_DESCRIPTION, TOPIC_EVENTS, TOPIC_LOG})
WORLD_FRAME = "world"
RUN_STATUSES = ("completed", "diverged", "interrupted", "failed")

_TOPIC_RE = re.compile(r"^(/[A-Za-z0-9_]+)+$")
_SEP = b"\x00"  # never inside JSON text (control characters are escaped in strings)
_TS_MARK = b"\x01"  # marker where the timestamp object goes inside /tf templates
_NUM = b"%.12g"
_NANO = b"%de-9"  # a pose number as an integer count of 1e-9 (valid JSON: 1234567890e-9 = 1.23456789)
_NANO_LIMIT = 9.0e9  # |value| below which value·1e9 fits an int64
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


def _number_bytes(v: Any) -> bytes:
    """``%.12g`` of a finite number, ``null`` otherwise (slow path of non-finite samples)."""
    f = float(v)
    return _NUM % f if math.isfinite(f) else b"null"


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
    """Encoding plan for one set of numeric topics (the keys of a ``scalars`` dict, in order)."""

    def __init__(self, topics: list[str], fields: list[list[tuple[str, int]]], channels: list[int], indexes: list[list[int]]):
        self.topics = topics
        self.fields = fields
        self.channels = channels
        self.indexes = indexes
        parts_num = []
        parts_str = []
        for spec in fields:
            pieces_num = []
            pieces_str = []
            for name, n in spec:
                key = json.dumps(name, ensure_ascii=False).encode().replace(b"%", b"%%") + b":"
                if n == 0:
                    pieces_num.append(key + _NUM)
                    pieces_str.append(key + b"%b")
                else:
                    pieces_num.append(key + b"[" + b",".join([_NUM] * n) + b"]")
                    pieces_str.append(key + b"[" + b",".join([b"%b"] * n) + b"]")
            parts_num.append(b"{" + b",".join(pieces_num) + b"}")
            parts_str.append(b"{" + b",".join(pieces_str) + b"}")
        self.template = _SEP.join(parts_num)
        self.template_str = _SEP.join(parts_str)
        self.rows = list(zip(topics, fields))


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
        self._tf_template = b""
        self._tf_channel = 0
        self._tf_index: list[int] | None = None

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
        pose = b'"translation":{"x":%b,"y":%b,"z":%b},"rotation":{"x":%b,"y":%b,"z":%b,"w":%b}}'
        heads = []
        for link, parent in zip(links, parents):
            names = b',"parent_frame_id":%b,"child_frame_id":%b,' % (_json_bytes(parent), _json_bytes(link))
            heads.append(b'{"timestamp":' + _TS_MARK + names.replace(b"%", b"%%"))
        self._tf_pieces = [head + pose % ((_NUM,) * 7) for head in heads]  # slow path: %.12g per link
        self._tf_template = _SEP.join(head + pose % ((_NANO,) * 7) for head in heads)
        if self._w is not None:
            self._busy = True
            try:
                self._register_tf()
            finally:
                self._end_busy()

    def _register_tf(self) -> None:
        w = self._w
        sid = w.register_schema(fs.FRAME_TRANSFORM["title"], "jsonschema", fs.schema_bytes(fs.FRAME_TRANSFORM))
        self._tf_channel = w.register_channel(TOPIC_TF, "json", sid)
        self._tf_index = w.channel_index(self._tf_channel)

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
        if self.finished:
            raise RuntimeError("recorder: write_step after finish()")
        ts = _to_ns(t)
        if ts <= self._last_ts:
            if ts == self._last_ts:
                return False  # already recorded at this time (e.g. a forced final sample)
            raise ValueError(f"recorder: time went backwards: t = {t!r} s after a sample at {self._last_ts / 1e9!r} s")
        if self._w is None:
            self._ensure_open()

        # encode everything first: a bad argument raises before anything is appended
        tf_payloads = self._encode_tf(ts, transforms) if transforms is not None else None
        if scalars:
            plan = self._plans.get(tuple(scalars))
            if plan is None:
                self._busy = True
                try:
                    plan = self._plan(scalars)
                finally:
                    self._end_busy()
            payloads = self._encode_scalars(plan, scalars)
        else:
            plan = payloads = None

        self._busy = True
        try:
            if not self._started:
                self._start(ts)
            w = self._w
            buf = w.chunk_buffer()
            pack = MESSAGE_HEADER.pack
            seq = self._samples & 0xFFFFFFFF
            if tf_payloads:
                cid = self._tf_channel
                index = self._tf_index
                for data in tf_payloads:
                    index.append(ts)
                    index.append(len(buf))
                    buf += pack(5, MESSAGE_FIXED + len(data), cid, seq, ts, ts)
                    buf += data
            if payloads is not None:
                for cid, index, data in zip(plan.channels, plan.indexes, payloads):
                    index.append(ts)
                    index.append(len(buf))
                    buf += pack(5, MESSAGE_FIXED + len(data), cid, seq, ts, ts)
                    buf += data
            if len(buf) >= w.chunk_size:
                w.flush_chunk()
            self._samples += 1
            self._last_ts = ts
            if self._t0 is None:
                self._t0 = t
            self._next_t = self._next_due(t, self._t0)
        finally:
            self._end_busy()
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
        picked = []
        i = 0
        while True:
            i = max(i, int(np.searchsorted(times, self._next_t, side="left")))  # first offer at or after the due time
            if i >= times.size:
                break
            picked.append(i)
            self._reserve(float(times[i]))
            i += 1
        return np.array(picked, dtype=np.intp)

    def write_block(self, times: np.ndarray, *, transforms: np.ndarray | None = None,
                    scalars: Mapping[str, Mapping[str, Any]] | None = None, relative: bool = False) -> None:
        """Record n samples at once (the rows ``select`` picked): ``times`` (n,) increasing,
        ``transforms`` (n, n_links, 7) world poses (``relative``: already each link's pose in its
        parent, as /tf carries them), ``scalars`` topic → {field: (n,) or (n, k)}.
        The same messages as n ``write_step(..., force=True)`` calls, encoded and framed in one
        compiled pass (``mcap_block``); a block with a non-finite or huge pose falls back to
        those calls."""
        times = np.asarray(times, dtype=float)
        n = times.size
        if n == 0:
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
        columns = []  # one row of numbers per sample, in template order
        n_tf = 0
        if transforms is not None:
            rel = self._block_poses(transforms, n, relative)
            scaled = rel * 1e9
            if not (-_NANO_LIMIT * 1e9 < scaled.min() and scaled.max() < _NANO_LIMIT * 1e9):  # False for NaN
                return self._write_rows(times, rel if self._tf_rel is None or relative else transforms, scalars,
                                        relative)
            n_tf = len(self._links)
            sec, nsec = np.divmod(ts, 1_000_000_000)
            stamp = np.broadcast_to(np.stack([sec, nsec], axis=1)[:, None, :].astype(float), (n, n_tf, 2))
            columns.append(np.concatenate([stamp, scaled.reshape(n, n_tf, 7)], axis=2).reshape(n, -1))
        plan = None
        if scalars:
            first = {topic: {name: np.asarray(val)[0] for name, val in fields.items()} for topic, fields in scalars.items()}
            plan = self._plans.get(tuple(first))
            if plan is None:
                self._busy = True
                try:
                    plan = self._plan(first)
                finally:
                    self._end_busy()
            columns.append(self._block_values(plan, scalars, n))
        key = (n_tf, tuple(plan.topics) if plan is not None else ())
        tpl = self._block_templates.get(key)
        if tpl is None:
            stamp_tpl = b'{"sec":%d,"nsec":%d}'
            texts = [piece.replace(_TS_MARK, stamp_tpl) for piece in self._tf_template.split(_SEP)] if n_tf else []
            texts += plan.template.split(_SEP) if plan is not None else []
            tpl = self._block_templates[key] = (Templates(texts), np.array(
                [self._tf_channel] * n_tf + (list(plan.channels) if plan is not None else []), dtype=np.int64))
        templates, channels = tpl
        values = np.ascontiguousarray(np.hstack(columns), dtype=float)
        out = np.empty(templates.capacity(n), dtype=np.uint8)
        offsets = np.empty(n * templates.n_messages, dtype=np.int64)
        self._busy = True
        try:
            if not self._started:
                self._start(int(ts[0]))
            end = encode_records(templates.lit, templates.lit_start, templates.lit_len, templates.code,
                                 templates.piece_start, values, channels, self._samples, ts, out, offsets)
            self._append_records(out, end, offsets, np.repeat(ts, templates.n_messages), np.tile(channels, n))
            self._samples += n
            self._last_ts = int(ts[-1])
            if self._t0 is None:
                self._t0 = float(times[0])
            self._next_t = max(self._next_t, self._next_due(float(times[-1]), self._t0))
        finally:
            self._end_busy()

    def _write_rows(self, times, transforms, scalars, relative: bool) -> None:
        """The per-sample path for a block (non-finite or huge poses need its slow encoding)."""
        tf_rel = self._tf_rel
        if relative:
            self._tf_rel = None  # the rows are parent-relative already
        try:
            for i, t in enumerate(times):
                row = {topic: {name: np.asarray(val)[i] for name, val in fields.items()}
                       for topic, fields in (scalars or {}).items()}
                self._record(float(t), None if transforms is None else np.asarray(transforms)[i], row or None)
        finally:
            self._tf_rel = tf_rel

    def _append_records(self, out: np.ndarray, end: int, offsets: np.ndarray, msg_ts: np.ndarray,
                        msg_channel: np.ndarray) -> None:
        """Move framed records into chunks (flushing full ones) and extend the message indexes."""
        w = self._w
        rec_end = np.append(offsets[1:], end)
        total = offsets.size
        i = 0
        while i < total:
            buf = w.chunk_buffer()
            room = max(w.chunk_size - len(buf), 1)
            j = min(int(np.searchsorted(rec_end, offsets[i] + room, side="left")) + 1, total)
            base = len(buf) - int(offsets[i])
            buf += out[offsets[i]:rec_end[j - 1]].data
            chans = msg_channel[i:j]
            for cid in np.unique(chans).tolist():
                sel = np.nonzero(chans == cid)[0] + i
                w.channel_index(cid).extend(np.column_stack([msg_ts[sel], offsets[sel] + base]).ravel().tolist())
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

    def _block_values(self, plan: _ScalarPlan, scalars, n: int) -> np.ndarray:
        """The numeric topics' values (n, n_values) in the plan's template order."""
        cols = []
        for topic, spec in plan.rows:
            fields = scalars[topic]
            if len(fields) != len(spec) or any(name not in fields for name, _ in spec):
                raise ValueError(f"recorder: the fields of {topic} changed: first {spec}, now {sorted(fields)}")
            for name, k in spec:
                col = np.asarray(fields[name], dtype=float)
                want = (n,) if k == 0 else (n, k)
                if col.shape != want:
                    raise ValueError(f"recorder: block field {topic}.{name} must have shape {want}, got {col.shape}")
                cols.append(col.reshape(n, -1))
        return np.hstack(cols)

    def _encode_tf(self, ts: int, transforms) -> list[bytes]:
        if self._links is None:
            raise ValueError("recorder: transforms given but add_transform_tree was not called")
        world = transforms if isinstance(transforms, np.ndarray) else np.asarray(transforms, dtype=float)
        n = len(self._links)
        if world.shape != (n, 7):
            raise ValueError(f"recorder: transforms must have shape ({n}, 7) (one [x y z qx qy qz qw] row per link), got {world.shape}")
        rel = world if self._tf_rel is None else self._tf_rel(world)
        scaled = rel * 1e9
        if -_NANO_LIMIT * 1e9 < scaled.min() and scaled.max() < _NANO_LIMIT * 1e9:  # False for NaN
            text = self._tf_template % tuple(np.rint(scaled).astype(np.int64).ravel().tolist())
            return text.replace(_TS_MARK, _time_json(ts)).split(_SEP)
        # slow path (non-finite or beyond ±9e9): %.12g, and links whose pose is not finite left out
        stamp = _time_json(ts)
        flat = rel.ravel().tolist()
        out = []
        for i, piece in enumerate(self._tf_pieces):
            row = flat[7 * i : 7 * i + 7]
            if all(math.isfinite(v) for v in row):
                out.append((piece % tuple(row)).replace(_TS_MARK, stamp))
        return out

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
        plan = _ScalarPlan(topics, fields_all, channels, [self._w.channel_index(c) for c in channels])
        self._plans[tuple(topics)] = plan
        return plan

    def _register_topic(self, topic: str, spec: list[tuple[str, int]]) -> None:
        schema = fs.numeric_topic_schema(topic, spec)
        sid = self._w.register_schema(schema["title"], "jsonschema", fs.schema_bytes(schema))
        self._topic_channels[topic] = self._w.register_channel(topic, "json", sid)

    def _encode_scalars(self, plan: _ScalarPlan, scalars) -> list[bytes]:
        vals: list = []
        app = vals.append
        ext = vals.extend
        try:
            for topic, spec in plan.rows:
                fields = scalars[topic]
                if len(fields) != len(spec):
                    raise KeyError
                for name, n in spec:
                    v = fields[name]
                    if n:
                        try:
                            lst = v.tolist()
                        except AttributeError:
                            lst = list(v)
                        if len(lst) != n:
                            raise KeyError
                        ext(lst)
                    else:
                        app(v)
            total = sum(vals)
            if total - total == 0:
                return (plan.template % tuple(vals)).split(_SEP)
            return (plan.template_str % tuple(_number_bytes(v) for v in vals)).split(_SEP)
        except (KeyError, TypeError, ValueError):
            raise ValueError(self._scalar_mismatch(plan, scalars)) from None

    def _scalar_mismatch(self, plan: _ScalarPlan, scalars) -> str:
        for topic, spec in plan.rows:
            fields = scalars[topic]
            want = {name: n for name, n in spec}
            got = {}
            for name, value in fields.items():
                arr = np.asarray(value)
                got[name] = 0 if arr.ndim == 0 else (arr.size if arr.ndim == 1 else arr.shape)
            if got != want:
                return f"recorder: the fields of {topic} changed: first {spec}, now {sorted(got.items())} (0 = number, n = array length)"
            for name, _ in spec:
                try:
                    np.asarray(fields[name], dtype=float)
                except (TypeError, ValueError):
                    return f"recorder: {topic}.{name} is not numeric: {fields[name]!r}"
        return "recorder: scalars are not numbers or arrays of numbers"

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
            _number_bytes(t), json.dumps(str(name), ensure_ascii=False).encode(), level.encode(), detail_json.encode()
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
