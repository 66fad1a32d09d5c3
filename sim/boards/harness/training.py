"""The training run of the harness's profile-guided build (:func:`fliss.sim.boards.harness.build`).

``python -m fliss.sim.boards.harness.training LIBRARY BAUD CYCLES`` runs the fast board in the
harness ``LIBRARY`` (built with ``-fprofile-generate``, its UART at ``BAUD``) on the paper's
set-up for ``CYCLES`` clock cycles: the single pixel, 1 MHz PRF, the aggressor on, histograms
made and sent; the compiler then optimises the model for the branches this run took. The
profile is written when the process ends.
"""

import sys

from ....hdl.clock import DEFAULT_CLOCK_HZ
from ....hdl.protocol import PacketType, registers_layout
from ....hdl.registers import BY_NAME
from ....protocol import PacketEncoder, pack
from ..fast import POLL_CYCLES, FastBoard
from ..virtual import scene_from_environment


__all__ = ["train"]


def train(library, baud, cycles):
    """Run the board in ``library`` for ``cycles`` clock cycles of acquisition."""
    board = FastBoard(library, scene_from_environment(), baud=baud, seed=1)
    board.start()
    harness = board.harness
    encoder = PacketEncoder()
    commands = encoder.frame(PacketType.WRITE, pack(
        registers_layout(1), address=BY_NAME["aggressor"].address, values=[1])) + \
        encoder.frame(PacketType.START)
    harness.write(commands)
    # The commands take their time on the line first (a frame of bytes of 10 bits each; at
    # 9600 baud, more than the training run itself): the acquisition is awaited for four times
    # that, then trained on for ``cycles``.
    line_cycles = len(commands) * 10 * DEFAULT_CLOCK_HZ // baud
    started_by = harness.cycle + 4 * line_cycles + POLL_CYCLES
    while not harness.running and harness.cycle < started_by:
        board.run(POLL_CYCLES)
        harness.read()
    if not harness.running:
        raise SystemExit("the training run did not start the acquisition")
    end = harness.cycle + cycles
    while harness.cycle < end:
        board.run(POLL_CYCLES)
        harness.read()
    harness.close()


if __name__ == "__main__":
    train(sys.argv[1], int(sys.argv[2]), int(sys.argv[3]))
