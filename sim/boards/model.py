"""A FLISS board in Python, behind a pseudo-terminal: for host tests and for demos without a
simulator.

:class:`ModelBoard` speaks the real protocol bytes (:mod:`fliss.hdl.protocol`) over a pty: it
decodes commands with the software codec (:mod:`fliss.protocol`), answers them with
:class:`fliss.sim.models.command.CommandModel` (the reply semantics of the gateware command processor)
and, while acquiring, sends the data packets of its readout (HISTOGRAM chunks, DEPTH frames or
EVENTS batches, each made by its producer in :mod:`fliss.sim.boards.producers`) made from the
photon scene simulator (:mod:`fliss.sim.scene`) with the configured delay settings, paced by the
wall clock.

It is a behavioural model of the whole board, not a cycle-accurate one: frame ``k`` of an
acquisition holds the laser cycles whose TDC start falls in clock cycles ``[k I, (k + 1) I)``
(``I`` = ``integration``), exactly as :func:`fliss.sim.scene.acquire` cuts a run, so a test can
predict every histogram from the scene and the seeds.

Faults can be injected (:class:`fliss.sim.boards.pty_server.PtyServer`): ``kill_after`` closes the pty
after that many data packets (a board unplugged mid-capture), ``hang_after`` stops sending
without closing, ``reset_after`` resets the board (a power cycle mid-capture: registers,
counters, histogram and sequence numbers back to reset, acquisition stopped), and ``corrupt_every`` damages one byte of every n-th frame sent (never a
delimiter, never into a delimiter), keeping the list of what it damaged in
:attr:`ModelBoard.corrupted`.

``python -m fliss.sim.boards.model`` serves one on a pty, with ``fliss board``'s options."""

import time
from contextlib import contextmanager

import numpy as np

from ...hdl.clock import DEFAULT_CLOCK_HZ
from ...hdl.histogram.layout import MAX_COUNT_WIDTH
from ...hdl.protocol import (DEFAULT_BAUD, PacketType, STATUS_FIELDS, LINK_COUNTERS,
                             version_numbers)
from ...hdl.delay.modes import MODES, DelayMode
from ...hdl.event import TDC_LSB_S
from ...hdl.finetdc import TAP_S as FINE_TAP_S
from ...hdl.tdc import MAX_TIMESTAMP
from ...hdl.registers import (AGGRESSOR_DELAY, VICTIM, AcquisitionMode, TdcSource, group_values,
                              value_of, words_of)
from ...protocol.frames import LinkError, Packet, packet_type
from ..models import scheduler as _scheduler
from ..models import histogram as _histogram
from ..models.command import CommandModel
from ...protocol.histograms import decode_chunk, frame_bins
from ...protocol.packets import HISTOGRAM_TYPES
from .loopback import Loopback
from .producers import PRODUCERS
from .pty_server import PtyServer
from ..scene import Aggressor, Scene, simulation_for


__all__ = ["DEFAULT_BAUD", "BACKLOG_BYTES", "ModelBoard", "scene_for", "model_board"]


#: While more bytes than this wait to go out, the model simulates no further: a host slower
#: than the model slows the model's time down rather than piling up data (the gateware would
#: drop histograms or events instead, and count them).
BACKLOG_BYTES = 32 * 1024


class _NoPulses:
    """A simulation of a run without a laser pulse or TDC start: nothing to simulate."""
    next_start_cycle = None


def scene_for(settings, template=None, *, aggressor_detections_per_pulse=0.05, clock_hz=None):
    """The scene a board with register ``settings`` (by name) sees: ``template`` (a
    :class:`Scene`, for the physics, and its pixel array if it has one: then the events carry
    the pixels' addresses and collision flags) with the victim and aggressor taken from the
    registers. The aggressor lights every pixel (a flash)."""
    template = Scene() if template is None else template
    clock_hz = template.clock_hz if clock_hz is None else clock_hz
    s = settings
    victim = _scheduler.Settings(**_delay_settings(s, VICTIM), key=value_of(s, "key"),
                                 iv=value_of(s, "iv"))
    aggressors = ()
    if s["aggressor"]:
        delays = _delay_settings(s, AGGRESSOR_DELAY)
        mode = delays["mode"]
        aggressors = (Aggressor(
            period_cycles=delays["period"], offset_s=s["aggressor_offset"] / clock_hz,
            detections_per_pulse=aggressor_detections_per_pulse, mode=mode,
            **{name: delays[name] for name in MODES[mode].needs}),)
    return template.replace(victim=victim, aggressors=aggressors, clock_hz=clock_hz)


def _delay_settings(values, group):
    # The settings of a delay core (its register `group`) in register `values`, by field, as
    # the models take them
    fields = group_values(group, values)
    return {**fields, "mode": DelayMode(fields["mode"]), "grid": bool(fields["grid"])}


class ModelBoard(PtyServer):
    """A board on a pseudo-terminal, served by a thread (a
    :class:`~fliss.sim.boards.pty_server.PtyServer`).

    Parameters
    ----------
    clock_hz : int
        Clock frequency reported in the identity and used for all times.
    baud : int
        Baud rate reported in the identity.
    scene : Scene or None
        Physics of the scene (distance, photon rates, background…); victim and aggressor come
        from the registers at each START.
    photon_seed : int
        Seed of the photon statistics; the ``n``-th acquisition (START) since the board was
        made uses :meth:`seed_for` ``(n)``.
    time_scale : float
        Simulated seconds per wall-clock second.
    kill_after, hang_after, reset_after, corrupt_every, corrupt_seed, corrupt_types, corrupt_commands_every
        Faults of the line, as in :class:`~fliss.sim.boards.pty_server.PtyServer`.
    keep_sent : bool
        Keep the record of what was sent (:class:`~fliss.sim.boards.pty_server.PtyServer`);
        False for long runs.
    protocol_version : int or None
        Report this protocol version instead of the real one.
    gateware_version : str or None
        Report this gateware version (``"0.1.0"``) instead of the package's.
    line_limited : bool
        In raw mode, send no more events per block of ``integration`` cycles than the line
        carries at ``baud`` in full EVENTS frames; drop the rest at the raw FIFO and count them
        in ``dropped_fifo``, as the gateware does. (A pty itself carries anything.)
    maxima : dict
        Register maxima of a smaller build (:meth:`fliss.hdl.top.FlissTop.register_maxima`).
    loopback : Loopback or None
        What reaches the TDCs besides the scene (:mod:`fliss.sim.boards.loopback`): a jumper
        wire, the fine TDC's on-chip oscillator and internal loopback; while it drives the TDC,
        its hits replace the scene's photons. None: ``Loopback(jumper=None)``, no jumper wire.
    """

    def __init__(self, *, clock_hz=DEFAULT_CLOCK_HZ, baud=DEFAULT_BAUD, scene=None,
                 aggressor_detections_per_pulse=0.05, photon_seed=0, time_scale=1.0,
                 kill_after=None, hang_after=None, reset_after=None, corrupt_every=None,
                 corrupt_seed=1, corrupt_types=None, corrupt_commands_every=None,
                 protocol_version=None, gateware_version=None, line_limited=False, maxima=None,
                 loopback=None, keep_sent=True):
        super().__init__(kill_after=kill_after, hang_after=hang_after, reset_after=reset_after,
                         corrupt_every=corrupt_every, corrupt_seed=corrupt_seed,
                         corrupt_types=corrupt_types,
                         corrupt_commands_every=corrupt_commands_every, keep_sent=keep_sent)
        self.clock_hz = int(clock_hz)
        self.baud = int(baud)
        self.template = Scene(clock_hz=self.clock_hz) if scene is None else scene
        self.aggressor_detections_per_pulse = aggressor_detections_per_pulse
        self.photon_seed = photon_seed
        self.time_scale = float(time_scale)
        self.protocol_version = protocol_version
        self.gateware_version = gateware_version
        #: Send only this many bytes of the identity (an older protocol's shorter identity).
        self.identity_length = None
        self.line_limited = line_limited
        self.maxima = maxima
        self.loopback = Loopback(jumper=None) if loopback is None else loopback
        self._looped = None
        self.model = CommandModel(self.clock_hz, self.baud, maxima=maxima, keyed_source=True)
        self.status = dict.fromkeys(STATUS_FIELDS, 0)
        #: Acquisitions started so far (each START while stopped).
        self.starts = 0
        #: The producer of each readout, whose frame numbers count from reset.
        self.producers = {readout: producer() for readout, producer in PRODUCERS.items()}

    def sent_histograms(self, bins, *, whole=False):
        """The histograms sent so far, from this board's own record (``sent``): counts of
        ``bins`` bins by frame number, from both chunk forms; with ``whole``, only those whose
        last chunk was sent."""
        sent, ended = {}, set()
        for type_value, _seq, payload in list(self.sent):
            if packet_type(type_value) not in HISTOGRAM_TYPES:
                continue
            chunk = decode_chunk(packet_type(type_value), payload)
            first = chunk.first_bin
            sent.setdefault(chunk.frame, np.zeros(bins, np.int64))[
                first:first + len(chunk.counts)] = chunk.counts
            if chunk.last:
                ended.add(chunk.frame)
        return {frame: counts for frame, counts in sent.items() if not whole or frame in ended}

    def seed_for(self, acquisition):
        """Seed of the photon statistics of acquisition ``acquisition`` (0 for the first START)."""
        return np.random.SeedSequence([self.photon_seed, acquisition])

    @property
    def running(self):
        return self.model.running

    @property
    def next_frame(self):
        """Number the next histogram will carry (frames count from 0 since the board was
        made)."""
        return self.producers[AcquisitionMode.HISTOGRAM].number

    @property
    def simulated_s(self):
        """Seconds of board time the current (or last) acquisition has simulated: the wall
        clock's time since its START, or less when the model or the host is slower than real
        time (it never runs ahead)."""
        return getattr(self, "_done_cycles", 0) / self.clock_hz

    # Serving

    @property
    def _busy(self):
        return self.model.running

    def _work(self, now):
        if self.model.running and len(self._out) < BACKLOG_BYTES:
            self._advance(now)

    @property
    def _due(self):
        # A block due already (the model behind the clock) and room to send it
        if not self.model.running or len(self._out) >= BACKLOG_BYTES:
            return False
        integration = self.settings["integration"]
        block_end = (self._done_cycles // integration + 1) * integration
        return block_end <= self._cycles_at(time.monotonic())

    def _killed(self):
        self.model.running = False

    def _reset(self):
        self.model = CommandModel(self.clock_hz, self.baud, maxima=self.maxima,
                                  keyed_source=True)
        self.status = dict.fromkeys(STATUS_FIELDS, 0)
        self._frame_counts = None
        for producer in self.producers.values():
            producer.reset()

    def _receive(self, item):
        if isinstance(item, LinkError):
            self.status[LINK_COUNTERS[item.code]] += 1
            self._send(*self.model.link_error(item.code))
            return
        if not isinstance(item, Packet):
            return
        type_value = item.type.value if isinstance(item.type, PacketType) else item.type
        was_running = self.model.running
        if type_value == PacketType.STOP.value and was_running and not item.payload:
            # The frame in progress ends now; its data follow the ACK, as from the gateware.
            reply = self.model.command(type_value, item.seq, item.payload, self.status)
            self._send(*reply)
            self._advance(time.monotonic(), final=True)
            return
        reply = self.model.command(type_value, item.seq, item.payload, self.status)
        if type_value == PacketType.IDENTIFY.value and self.protocol_version is not None \
                and reply[0] == PacketType.IDENTITY:
            reply = (reply[0], bytes([self.protocol_version]) + reply[1][1:])
        if type_value == PacketType.IDENTIFY.value and self.gateware_version is not None \
                and reply[0] == PacketType.IDENTITY:
            version = bytes(version_numbers(self.gateware_version))
            reply = (reply[0], reply[1][:1] + version + reply[1][1 + len(version):])
        if type_value == PacketType.IDENTIFY.value and self.identity_length is not None \
                and reply[0] == PacketType.IDENTITY:
            reply = (reply[0], reply[1][:self.identity_length])
        self._send(*reply)
        if type_value == PacketType.START.value and self.model.running and not was_running:
            self._begin(time.monotonic())

    # Acquisition

    def _begin(self, now):
        # (the keyed source runs with the IV in use)
        settings = {**self.model.settings, **words_of(self.model.iv_in_use, "iv")}
        self.settings = dict(settings)
        scene = scene_for(settings, self.template,
                          aggressor_detections_per_pulse=self.aggressor_detections_per_pulse,
                          clock_hz=self.clock_hz)
        self.simulation = simulation_for(scene, seed=self.seed_for(self.starts))
        self.starts += 1
        self.status["pulses"] = 0       # the scheduler's pulse index restarts, as in the gateware
        self._t0 = now
        self._done_cycles = 0           # clock cycles simulated
        self._frame_counts = None
        self._producer = self.producers[AcquisitionMode(settings["acquisition"])]
        self._producer.begin()
        self._looped = self.loopback.run(settings, scene.victim, self.clock_hz,
                                         self.model.table, self.seed_for(self.starts))
        if self.model.no_pulses:
            # (the keyed source has used every IV under its key: no laser pulse, no TDC start)
            self.simulation, self._looped = _NoPulses(), None

    def _cycles_at(self, now):
        return int((now - self._t0) * self.time_scale * self.clock_hz)

    def _advance(self, now, final=False):
        """Simulate up to the present (up to a stop with ``final``) and send what is due.

        Time is simulated in blocks of ``integration`` clock cycles (the random draws depend
        only on the settings and the seed, not on the wall clock): one histogram per block, or
        the block's events. At a stop the block in progress is simulated up to the stop and
        sent too, as the gateware reads out a shortened frame.
        """
        integration = self.settings["integration"]
        target = self._cycles_at(now)
        block_end = (self._done_cycles // integration + 1) * integration
        if final:
            # A model slower than real time stops where it has got to, within a block.
            self._block(min(max(target, self._done_cycles), block_end))
            self._producer.send(self, final=True)
            return
        # One block at a time, so that commands are served while the model catches up.
        if block_end <= target:
            self._block(block_end)
            self._producer.send(self, final=False)

    def _block(self, end):
        events = self._events(self._simulate(end))
        self._done_cycles = end
        if self._producer.histograms:
            self._accumulate(events)
            s = self.settings
            counts = self._frame_counts if self._frame_counts is not None else \
                np.zeros(frame_bins(s["bin_shift"], s.get("pixel_bits", 0)), dtype=np.int64)
            self._frame_counts = None
            self._producer.frame(self, counts)

    def _simulate(self, end):
        simulation = self.simulation
        pieces = []
        while simulation.next_start_cycle is not None and simulation.next_start_cycle < end:
            chunk = simulation.step(until_cycle=end)
            self.status["pulses"] += chunk.cycles
            pieces.append(chunk.events)
        looped = self._looped and self._looped.events(self._done_cycles, end)
        if looped:
            events, overflow = looped
            self.status["dropped_overflow"] += overflow
            return events
        if not pieces:
            return None
        return np.concatenate(pieces)

    def _events(self, events):
        """Apply the TDC source and gate to simulated events and count them."""
        if events is None or len(events) == 0:
            return events
        s = self.settings
        events = events.copy()
        if self._looped is not None and self._looped.kind is not None:
            pass    # (a loopback's events are already the selected TDC's codes)
        elif s["tdc_source"] == TdcSource.COARSE.value:
            lsb_per_cycle = int(round(self.simulation.scene.lsb_per_cycle))
            events["timestamp"] //= lsb_per_cycle
        elif s["tdc_source"] == TdcSource.FINE.value:
            # The fine TDC, ideal: the scene's 50 ps codes at its LSB (the scene has no finer
            # detail); beyond 13 bits the event filter drops them as overflows
            stamps = events["timestamp"].astype(np.int64) << s["fine_lsb"]
            events = events[stamps <= MAX_TIMESTAMP]
            events["timestamp"] = stamps[stamps <= MAX_TIMESTAMP]
        elif s["tdc_source"] == TdcSource.FINE_RAW.value:
            # Its raw codes with taps as the timing model has them: the taps a photon passed
            # before the next clock edge
            lsb_per_cycle = self.simulation.scene.lsb_per_cycle
            before = (-events["timestamp"].astype(np.float64) - 0.5) % lsb_per_cycle
            events["timestamp"] = 1 + np.floor(before * TDC_LSB_S / FINE_TAP_S).astype(np.int64)
        if s["collisions"]:     # (the event filter drops flagged events before the gate)
            flagged = events["collision"] != 0
            self.status["dropped_collision"] += int(np.count_nonzero(flagged))
            events = events[~flagged]
        stamps = events["timestamp"]
        inside = (stamps >= s["gate_start"]) & (stamps <= s["gate_end"])
        self.status["dropped_gate"] += int(np.count_nonzero(~inside))
        events = events[inside]
        self.status["events"] += len(events)
        self._producer.take(self, events)
        return events

    def _accumulate(self, events):
        # Per-pixel histograms, flat in readout order (pixel << (13 - bin_shift) | bin);
        # events of other addresses are counted in dropped_pixel.
        s = self.settings
        split = dict(shift=s["bin_shift"], pixel_bits=s["pixel_bits"],
                     first_pixel=s["first_pixel"], bank_bits=self.model.bank_bits,
                     count_width=MAX_COUNT_WIDTH)
        if self._frame_counts is None:
            self._frame_counts = np.zeros(_histogram.bins_read(
                split["shift"], split["bank_bits"], split["pixel_bits"]), dtype=np.int64)
        if events is not None and len(events):
            counts, overflow, outside = _histogram.histogram(
                events["timestamp"], events["address"], **split)
            self._frame_counts += counts.ravel()
            self.status["histogram_overflow"] += overflow
            self.status["dropped_pixel"] += outside


@contextmanager
def model_board(**options):
    """A :class:`ModelBoard` on a pty for the duration of a ``with`` block; yields the board
    (its :attr:`~ModelBoard.path` is the pty to open)."""
    board = ModelBoard(**options)
    board.open()
    try:
        yield board
    finally:
        board.close()


if __name__ == "__main__":
    from .model_command import main
    raise SystemExit(main())
