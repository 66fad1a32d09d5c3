"""The training run of the harness's profile-guided build (:func:`fliss.sim.boards.harness.build`).

``python -m fliss.sim.boards.harness.training LIBRARY BAUD CYCLES`` runs the fast board in the
harness ``LIBRARY`` (built with ``-fprofile-generate``, its UART at ``BAUD``) on the paper's
set-up for ``CYCLES`` clock cycles: the single pixel, 1 MHz PRF, the aggressor on, histograms
made and sent; the compiler then optimises the model for the branches this run took. The
profile is written when the process ends.
"""

import sys

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
    harness.write(encoder.frame(PacketType.WRITE, pack(
        registers_layout(1), address=BY_NAME["aggressor"].address, values=[1])))
    harness.write(encoder.frame(PacketType.START))
    end = harness.cycle + cycles
    while harness.cycle < end:
        board.run(POLL_CYCLES)
        harness.read()
    if not harness.running:
        raise SystemExit("the training run did not start the acquisition")
    harness.close()


if __name__ == "__main__":
    train(sys.argv[1], int(sys.argv[2]), int(sys.argv[3]))
