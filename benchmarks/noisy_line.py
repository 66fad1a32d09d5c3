"""Captures through a noisy line (docs/verification.md, "A noisy line").

For each seed, the Python model board behind a :class:`fliss.sim.boards.noisy_line.NoisyLine` with a
bit error rate in both directions; the host captures histograms through it
(:func:`fliss.host.acquisition.capture`), then sets 32 register values and reads each back. It
prints what the line did (bits flipped, frames it damaged), what the host detected (corrupt
frames dropped, packets missing, commands re-sent, NAKs for damaged commands), the histograms
lost or incomplete in the file, and the wrong data accepted: histograms in the file that differ
from the board's own record of what it sent, and register values read back wrong.

Usage: python benchmarks/noisy_line.py [--ber 1e-4] [--seeds 5] [--acquisitions 100]
       [--bin-shift 6]
"""

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from fliss.host.acquisition import capture
from fliss.host.client import BoardClient
from fliss.host.fileformat import read_capture
from fliss.sim.boards.model import model_board
from fliss.sim.boards.noisy_line import LineFaults, NoisyLine


def frames_damaged(model, injector):
    ends = np.array([end for _type, _seq, end in model.frames_out])
    return len(set(np.searchsorted(ends, np.array(injector.faulty_offsets, dtype=np.int64),
                                   side="right").tolist()) - {len(ends)})


def run(ber, seed, acquisitions, shift, folder):
    faults = LineFaults(bit_error_rate=ber)
    bins = 8192 >> shift
    started = time.monotonic()
    with model_board() as model, \
            NoisyLine(model.path, to_host=faults, to_board=faults, seed=seed) as line:
        with BoardClient(line.path, timeout_s=0.5) as board:
            board.identify()
            board.write_registers({"bin_shift": shift})
            result = capture(board, folder / f"noisy-{seed}.h5", integration_s=1e-3,
                             acquisitions=acquisitions)
            wrong_registers = 0
            for value in range(1, 33):
                board.write_registers({"seed": value})
                wrong_registers += board.read_registers(["seed"]) != {"seed": value}
            # Counters of the whole session (capture and commands): the decoder's totals.
            counters = board.decoder.counters
            total = {"retransmissions": board.retransmissions, "link_naks": board.link_naks,
                     "dropped_frames": counters.dropped_frames,
                     "missing_packets": counters.missing_packets}
        sent = model.sent_histograms(bins)
        damaged = frames_damaged(model, line.to_host)
        counts = line.counts()
        board_link = sum(model.status[name] for name in ("bad_crc", "truncated", "oversize",
                                                         "bad_length"))
    data = read_capture(folder / f"noisy-{seed}.h5")
    wrong = 0
    for frame, row, complete in zip(data.frames, data.histograms, data.complete):
        truth = sent[int(frame)]
        wrong += (complete and not np.array_equal(row, truth)) or \
            (not complete and bool(np.any(row[row != truth])))
    return {
        "seed": seed, "s": time.monotonic() - started, "rows": len(data.frames),
        "bits_to_host": counts["to_host"]["bits_flipped"],
        "bits_to_board": counts["to_board"]["bits_flipped"],
        "damaged": damaged, "dropped": total["dropped_frames"],
        "missing": total["missing_packets"], "retried": total["retransmissions"],
        "naks": total["link_naks"], "board_detected": board_link,
        "lost": result.lost_histograms, "incomplete": int(np.count_nonzero(~data.complete)) - result.lost_histograms,
        "wrong": wrong + wrong_registers, "reason": result.reason}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ber", type=float, default=1e-4)
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--acquisitions", type=int, default=100)
    parser.add_argument("--bin-shift", type=int, default=6)
    args = parser.parse_args()
    columns = ["seed", "rows", "bits_to_host", "bits_to_board", "damaged", "dropped", "missing",
               "board_detected", "retried", "naks", "lost", "incomplete", "wrong", "s"]
    print(f"bit error rate {args.ber:g} both ways, {args.acquisitions} histograms of "
          f"{8192 >> args.bin_shift} bins (1 ms), then 32 register writes and reads")
    print(" ".join(f"{name:>13}" for name in columns), " end")
    with tempfile.TemporaryDirectory() as folder:
        for seed in range(args.seeds):
            row = run(args.ber, seed, args.acquisitions, args.bin_shift, Path(folder))
            print(" ".join(f"{row[name]:>13.1f}" if name == "s" else f"{row[name]:>13}"
                           for name in columns), "", row["reason"])


if __name__ == "__main__":
    main()
