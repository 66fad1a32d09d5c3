"""A long capture, measured: the host's memory, the file's size and every counter
over a given length of board time, in three phases, each a real ``fliss capture`` process on a
board's pty (as ``tests/test_survive.py`` runs it):

1. ``histogram``: 1 ms histograms (bin shift 3: 1024 bins) of the default single-pixel scene;
2. ``raw``: raw events at the link's limit: a scene whose events come at about 2.5 times what
   the UART carries in full EVENTS packets (:func:`fliss.protocol.events.link_events_per_s`),
   so that the board sends EVENTS packets back to back and drops the rest at its FIFO,
   counting them (the model board with ``line_limited``; the gateware by itself);
3. ``depth``: 1 ms depth frames of the same scene as the histograms.

Board time is the board's simulated time: the model board is paced by the wall clock but falls
behind it when the model or the host is slower (it never runs ahead), so its time is its
simulated clock cycles (:attr:`ModelBoard.simulated_s`); the fast virtual board's is the
cycles its statistics report. Each phase runs for ``--minutes`` of it: the framed readouts
capture that many integrations (``--acquisitions``), the raw capture is stopped by SIGINT
once the board has simulated that long (its end reason is then ``interrupted: SIGINT``).

Every ``--sample-s`` seconds of wall time it records the capture process's RSS (VmRSS of
/proc/PID/status), the file's size and the rows or events in it so far (read in single-writer
mode, as ``fliss view`` reads a capture being written); at the end it reads the file
(:func:`fliss.host.fileformat.read_capture`) and prints every counter it stores and a verdict
per phase:

* memory: ``flat`` when, over the second half of the samples, the RSS's least-squares slope
  is below :data:`FLAT_MB_PER_HOUR` MB per hour of board time, or the RSS stays within
  :data:`NOISE_MB` MB (allocator noise); ``unknown`` with fewer than :data:`MIN_SAMPLES`
  samples in that half; else ``GROWING`` with the slope;
* losses: the board's own count of what it made (frames, or events accepted past the gate)
  against the file and every counted drop; ``nothing lost`` only when that balance holds and
  every loss counter (board and host) is zero, ``every loss counted`` when it holds with
  counted drops, ``UNACCOUNTED`` when it does not, ``unknown`` without the board's counters.

Usage: python benchmarks/soak.py [--minutes 1] [--engine model|fast] [--sample-s 10]
[--phases histogram,raw,depth] [--folder DIR]
"""

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import replace, dataclass, field
from pathlib import Path

import h5py
import numpy as np

from fliss.host.fileformat import read_capture
from fliss.protocol.events import link_events_per_s
from fliss.sim.scene import Scene


PHASES = ("histogram", "raw", "depth")
#: Integration time of every phase, in seconds (raw mode: the model's block of events).
INTEGRATION_S = 1e-3
BIN_SHIFT = 3
#: Model board's baud rate (its default, the ULX3S build's) and the fast board's.
MODEL_BAUD, FAST_BAUD = 3_000_000, 12_000_000
#: Events per second the raw phase's scene gives, in units of what the link carries.
OVERFILL = 2.5
#: Memory verdict: most RSS growth called flat, MB per hour of board time, and the noise band.
FLAT_MB_PER_HOUR = 10.0
NOISE_MB = 2.0
MIN_SAMPLES = 4
#: Host counters that count something lost or damaged (``stream`` and ``link`` groups).
HOST_LOSSES = {"stream": ("lost_frames", "lost_rows", "lost_depth_frames", "incomplete_frames",
                          "incomplete_rows", "missing_bins", "malformed", "unexpected",
                          "queue_dropped_frames", "queue_dropped_events"),
               "link": ("bad_crc", "bad_length", "dropped_frames", "missing_packets", "oversize",
                        "sequence_gaps", "skipped_bytes", "truncated", "resyncs")}
#: Board counters that count an event or frame dropped or damaged.
BOARD_LOSSES = ("dropped_overflow", "dropped_overrun", "dropped_fifo", "dropped_histogram",
                "dropped_pixel", "histogram_overflow", "uart_framing_errors", "uart_overruns",
                "bad_crc", "truncated", "oversize", "bad_length")


def scene_for(phase, baud):
    """The scene of a phase: the default one; for raw, one bright enough to fill the link
    (1 MHz pulses: detections per pulse = OVERFILL x the link's events per microsecond)."""
    if phase != "raw":
        return Scene()
    per_pulse = OVERFILL * link_events_per_s(baud) / 1e6
    return Scene(detections_per_pulse=per_pulse)


@dataclass
class Sample:
    wall_s: float
    board_s: float
    rss_mb: float
    file_mb: float
    rows: int


@dataclass
class Phase:
    name: str
    path: Path
    target_s: float
    samples: list = field(default_factory=list)
    returncode: int = None
    stderr: str = ""
    board_s: float = 0.0
    wall_s: float = 0.0


# Boards


class ModelSoakBoard:
    """The Python model board, in this process (a thread behind a pty)."""

    def __init__(self, phase, seed):
        from fliss.sim.boards.model import ModelBoard
        self.board = ModelBoard(scene=scene_for(phase, MODEL_BAUD), baud=MODEL_BAUD,
                                photon_seed=seed, line_limited=True, keep_sent=False)
        self.board.open()
        self.path = self.board.path

    def board_s(self):
        return self.board.simulated_s

    def close(self):
        self.board.close()


class FastSoakBoard:
    """The fast virtual board (Verilator in the C++ harness), as ``fliss board --engine fast``
    runs it."""

    def __init__(self, phase, seed):
        from fliss.hdl.clock import DEFAULT_CLOCK_HZ
        from fliss.host.virtual import VirtualBoard
        scene = scene_for(phase, FAST_BAUD)
        self.board = VirtualBoard("verilator", engine="fast", baud=FAST_BAUD,
                                  signal=scene.detections_per_pulse,
                                  ambient_hz=scene.background_hz, seed=seed)
        self.clock_hz = DEFAULT_CLOCK_HZ
        self.path = self.board.start()
        self.started = None

    def board_s(self):
        # (from the first call, made as the capture starts: not the idle start-up before)
        cycles = self.board.stats().get("cycles", 0)
        if self.started is None:
            self.started = cycles
        return (cycles - self.started) / self.clock_hz

    def close(self):
        self.board.stop()


BOARDS = {"model": ModelSoakBoard, "fast": FastSoakBoard}


# Sampling


def rss_mb(pid):
    """VmRSS of process ``pid`` in MB (None once it has gone)."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    except OSError:
        pass
    return None


def rows_so_far(path, phase):
    """Rows (frames) or events in a capture file being written; None before it is readable."""
    dataset = {"histogram": "histograms/frame", "depth": "depth/frame",
               "raw": "events/events"}[phase]
    try:
        with h5py.File(path, "r", swmr=True) as f:
            return f[dataset].shape[0]
    except (OSError, KeyError, ValueError):
        return None


def capture_command(phase, port, path, target_s):
    frames = max(1, round(target_s / INTEGRATION_S))
    count = ["--duration", f"{max(3600.0, 100 * target_s):g}s"] if phase == "raw" else \
        ["--acquisitions", str(frames)]
    return [sys.executable, "-m", "fliss", "-q", "capture", "--port", port, "--timeout", "10",
            "--readout", phase, "--integration", f"{INTEGRATION_S * 1e3:g}ms",
            "--bin-shift", str(BIN_SHIFT), *count, "-o", str(path)]


def run_phase(engine, phase, target_s, folder, sample_s, seed, log):
    """One phase: a board, one ``fliss capture`` process, sampled until it ends."""
    result = Phase(phase, Path(folder) / f"soak-{engine}-{phase}.h5", target_s)
    result.path.unlink(missing_ok=True)
    board = BOARDS[engine](phase, seed)
    try:
        start = time.monotonic()
        board.board_s()
        # (its SIGINT as a terminal's: this script may run where SIGINT is ignored, as in a
        # background job, and a child inherits that, so the raw phase's stop would be lost)
        process = subprocess.Popen(capture_command(phase, board.path, result.path, target_s),
                                   stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                                   text=True, preexec_fn=_sigint_default)
        stopped, due = False, 0.0
        while True:
            ended = process.poll() is not None
            now = time.monotonic() - start
            if ended or now >= due:
                due = now + sample_s
                sample = Sample(now, board.board_s(), rss_mb(process.pid),
                                _size_mb(result.path), rows_so_far(result.path, phase))
                if sample.rss_mb:       # (0 or None: not yet started, or gone)
                    result.samples.append(sample)
                    log(format_sample(phase, sample))
                elif ended and result.samples:
                    # The file as the capture left it, with the RSS of its last sample (the
                    # process is gone): the table's last row is the file's end
                    log(format_sample(phase, replace(sample, rss_mb=result.samples[-1].rss_mb)))
            if ended:
                break
            # The raw capture stops when the board has run long enough (polled more often)
            if phase == "raw" and not stopped and board.board_s() >= target_s:
                process.send_signal(signal.SIGINT)
                stopped = True
            time.sleep(min(sample_s, 0.2))
        result.stderr = process.communicate()[1]
        result.returncode = process.returncode
        result.wall_s = time.monotonic() - start
        result.board_s = board.board_s()
    finally:
        board.close()
    return result


def _sigint_default():
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _size_mb(path):
    try:
        return os.path.getsize(path) / 1e6
    except OSError:
        return 0.0


# Verdicts


def memory_verdict(samples):
    """(word, detail) for the RSS of ``samples``: see the module's docstring."""
    half = [s for s in samples if s.board_s >= samples[-1].board_s / 2] if samples else []
    if len(half) < MIN_SAMPLES:
        return "unknown", f"{len(half)} samples in the second half, fewer than {MIN_SAMPLES}"
    rss = np.array([s.rss_mb for s in half])
    hours = np.array([s.board_s for s in half]) / 3600
    spread = rss.max() - rss.min()
    slope = np.polyfit(hours, rss, 1)[0] if np.ptp(hours) > 0 else float("inf")
    detail = (f"second half: RSS {rss.min():.1f}..{rss.max():.1f} MB, slope {slope:+.1f} "
              f"MB per board-hour (flat: below {FLAT_MB_PER_HOUR:g}, or within "
              f"{NOISE_MB:g} MB)")
    flat = spread <= NOISE_MB or slope < FLAT_MB_PER_HOUR
    return ("flat" if flat else "GROWING"), detail


def loss_verdict(phase, capture):
    """(word, lines) for the losses of a capture: the board's own count of what it made
    against the file and every counted drop."""
    counters = capture.counters
    if "board_end" not in counters or "board_start" not in counters:
        return "unknown", ["the file holds no board counters (the capture did not close)"]
    start, end = counters["board_start"], counters["board_end"]
    board = {name: end[name] - start.get(name, 0) for name in end}
    board["pulses"] = end["pulses"]     # (restarts at each START)
    stream = counters.get("stream", {})
    board_lost = {name: board[name] for name in BOARD_LOSSES if board.get(name)}
    host_lost = {f"{group}.{name}": counters.get(group, {}).get(name, 0)
                 for group, names in HOST_LOSSES.items() for name in names
                 if counters.get(group, {}).get(name, 0)}
    if phase == "raw":
        made, kept = board["events"], len(capture.events)
        dropped = board.get("dropped_fifo", 0) + stream.get("queue_dropped_events", 0)
        balance = made == kept + dropped
        lines = [f"board accepted {made} events of {board['pulses']} pulses "
                 f"({made / max(board['pulses'], 1):.4f} a pulse); file {kept}, board FIFO "
                 f"and host queue drops {dropped}: {kept} + {dropped} = {kept + dropped} "
                 f"{'==' if balance else '!='} {made}"]
    else:
        made = board["frames"]
        # rows: the frames that arrived, and blank rows (marked incomplete) for those that
        # did not, counted in lost_rows
        rows, blank = len(capture.frames), stream.get("lost_rows", 0)
        discarded = stream.get("discarded_frames", 0)
        incomplete = int(np.count_nonzero(~np.asarray(capture.complete, bool)))
        frames = capture.frames.astype(np.int64)
        gapless = bool(np.array_equal(frames, frames[0] + np.arange(len(frames)))) \
            if len(frames) else True
        counted = incomplete == blank + stream.get("incomplete_rows", 0)
        balance = made == rows + discarded and gapless and counted
        lines = [f"board made {made} frames; file {rows} rows (consecutive: {gapless}; "
                 f"{incomplete} marked incomplete, {blank} of them lost and "
                 f"{stream.get('incomplete_rows', 0)} arrived incomplete), after the last "
                 f"requested {discarded}: {rows} + {discarded} = {rows + discarded} "
                 f"{'==' if balance else '!='} {made}"]
    lines.append(f"board loss counters: {board_lost or 'all zero'}; host loss counters: "
                 f"{host_lost or 'all zero'}")
    if not balance:
        return "UNACCOUNTED", lines
    return ("nothing lost" if not board_lost and not host_lost else "every loss counted"), lines


# Output


def format_sample(phase, sample):
    rows = "-" if sample.rows is None else sample.rows
    return (f"{sample.wall_s:>9.1f} {sample.board_s:>9.3f} {phase:>9} {sample.rss_mb:>7.1f} "
            f"{sample.file_mb:>8.2f} {rows:>11}")


HEADER = f"{'wall s':>9} {'board s':>9} {'phase':>9} {'RSS MB':>7} {'file MB':>8} " \
         f"{'rows/events':>11}"


def report(engine, result, log):
    """The summary of one phase: its figures, every counter in its file, its verdicts."""
    capture = read_capture(result.path)
    # (RSS from the samples that found the file readable: the capture under way, its rows
    # perhaps still in the writer's batch)
    rss = [s.rss_mb for s in result.samples if s.rows is not None]
    kept = len(capture.events) if result.name == "raw" else len(capture.frames)
    log(f"phase {result.name} ({engine}): board {result.board_s:.3f} s of {result.target_s:g} "
        f"s in {result.wall_s:.1f} s wall; exit status {result.returncode}; end reason "
        f"{capture.attrs.get('end_reason')!r}")
    log(f"phase {result.name}: file {os.path.getsize(result.path) / 1e6:.3f} MB, "
        f"{kept} {'events' if result.name == 'raw' else 'frames'}; RSS first "
        f"{rss[0]:.1f} MB, last {rss[-1]:.1f} MB, max {max(rss):.1f} MB" if rss else
        f"phase {result.name}: no sample while the file was open (the capture ended at once)")
    for group in sorted(capture.counters):
        values = " ".join(f"{k}={v}" for k, v in sorted(capture.counters[group].items()))
        log(f"phase {result.name}: counters {group}: {values}")
    for problem in capture.problems:
        log(f"phase {result.name}: file problem: {problem}")
    if result.stderr.strip():
        log(f"phase {result.name}: capture stderr: {result.stderr.strip().splitlines()[-1]}")
    word, detail = memory_verdict(result.samples)
    log(f"verdict {result.name} memory: {word} ({detail})")
    word, lines = loss_verdict(result.name, capture)
    log(f"verdict {result.name} losses: {word} ({'; '.join(lines)})")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                     formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument("--minutes", type=float, default=1.0,
                        help="board time per phase, in minutes")
    parser.add_argument("--engine", choices=sorted(BOARDS), default="model")
    parser.add_argument("--sample-s", type=float, default=10.0,
                        help="wall-clock seconds between two samples")
    parser.add_argument("--phases", default=",".join(PHASES),
                        help="the phases to run, in this order")
    parser.add_argument("--seed", type=int, default=1, help="seed of the photon statistics")
    parser.add_argument("--folder", default=None,
                        help="keep the capture files here (default: a temporary folder)")
    args = parser.parse_args(argv)
    phases = [p for p in args.phases.split(",") if p]
    if not phases or set(phases) - set(PHASES):
        parser.error(f"--phases takes some of {','.join(PHASES)}, not {args.phases!r}")
    if not (args.minutes > 0 and args.sample_s > 0):
        parser.error("--minutes and --sample-s must be positive")

    def log(line):
        print(line, flush=True)

    if args.engine == "fast":
        skipped = fast_board_missing()
        if skipped:
            log(f"engine fast: skipped: {skipped}")
            return 0
    with tempfile.TemporaryDirectory() as scratch:
        folder = Path(args.folder or scratch)
        folder.mkdir(parents=True, exist_ok=True)
        log(f"soak on the {args.engine} board: {args.minutes:g} min of board time per phase "
            f"({', '.join(phases)}), a sample every {args.sample_s:g} s; files in {folder}")
        log(HEADER)
        results = [run_phase(args.engine, phase, args.minutes * 60, folder, args.sample_s,
                             args.seed, log) for phase in phases]
        for result in results:
            report(args.engine, result, log)
        total = sum(r.board_s for r in results)
        log(f"total: {total / 3600:.4f} h of board time in "
            f"{sum(r.wall_s for r in results) / 3600:.4f} h wall")
    return 0


def fast_board_missing():
    """Why the fast virtual board cannot run here (None if it can): Verilator and a C++
    compiler are needed to build its harness."""
    from fliss.host.errors import VirtualBoardError
    from fliss.host.virtual import VirtualBoard
    try:
        if not VirtualBoard("verilator", engine="fast", baud=FAST_BAUD).built:
            pass        # (built on the first start: some minutes)
    except VirtualBoardError as error:
        return str(error)
    return None


if __name__ == "__main__":
    raise SystemExit(main())
