"""What a producer of the model board is: :class:`Producer`, the data packets of one readout."""

__all__ = ["Producer"]


class Producer:
    """The data packets of one readout (``acquisition`` setting) of the model board
    (:class:`fliss.sim.boards.model.ModelBoard`), as the gateware's packetizer of that readout
    makes them.

    The board simulates time in blocks of ``integration`` clock cycles. It hands
    :meth:`take` the events each block accepts; when :attr:`histograms` is True it fills the
    block's per-pixel histogram and hands it to :meth:`frame` at the block's end; after each
    block, and at a stop with ``final``, it calls :meth:`send`. Each sends with
    ``board._send(type, payload, data=True)`` and counts frames in ``board.status``.
    Frame numbers count from the board's reset (:meth:`reset`)."""

    #: The ``acquisition`` setting (an ``AcquisitionMode``) whose packets this makes.
    readout = None
    #: Whether the board fills each block's per-pixel histogram for :meth:`frame`.
    histograms = False

    def reset(self):
        """The board was reset: frames are numbered from 0 again."""

    def begin(self):
        """An acquisition starts."""

    def take(self, board, events):
        """The events a block accepted (after the gate and filters)."""

    def frame(self, board, counts):
        """The block's per-pixel histogram ``counts``, flat in readout order."""

    def send(self, board, final):
        """After a block, or at a stop (``final``): send what is due."""
