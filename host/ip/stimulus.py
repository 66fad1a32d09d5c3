"""What the folder's testbench sends and expects: the bytes a host sends over the UART to set a
delay source and start, and the delays the reference model gives for it (``fliss sequence``)."""

from dataclasses import dataclass

from ...hdl.delay.modes import MODES
from ...hdl.protocol import PacketType, registers_layout
from ...hdl.registers import VICTIM
from ...protocol.frames import PacketEncoder
from ...protocol.layout import pack
from ...sim.models import delay as delay_model
from ...sim.models import scheduler as scheduler_model


__all__ = ["TB_MODES", "MAX_TB_DELAY", "DelayCheck"]


#: The delay sources the testbench can check: those with no key (the keyed source's delays
#: depend on an IV the board moves on).
TB_MODES = tuple(row.name for row in MODES.values() if not row.keyed)

#: Largest delay the testbench takes, in cycles: longer ones would simulate for hours.
MAX_TB_DELAY = 65535

#: The victim's settings the testbench writes, in register order (one WRITE).
_WRITTEN = ("mode", "length", "mask_width", "seed")


@dataclass(frozen=True)
class DelayCheck:
    """A delay source to set over the UART, and how many pulses to check.

    ``mode`` is a name of :data:`TB_MODES`; ``length``, ``mask_width`` and ``seed`` as the
    registers of the victim's delay source take them; ``period`` the victim's period in cycles
    (the register's reset value at the generated clock: the testbench leaves it).
    """
    mode: str
    length: int
    mask_width: int
    seed: int
    period: int
    pulses: int

    def settings(self):
        """The model's settings; :exc:`ValueError` names what is out of range."""
        if self.mode not in TB_MODES:
            raise ValueError(f"The testbench checks the delay sources {', '.join(TB_MODES)}, "
                             f"not {self.mode!r}")
        if not 2 <= self.pulses <= 4096:
            raise ValueError(f"The testbench checks 2 to 4096 pulses, not {self.pulses}")
        settings = scheduler_model.Settings(
            mode=delay_model.parse_mode(self.mode), length=self.length,
            mask_width=self.mask_width, seed=self.seed, period=self.period)
        for field in _WRITTEN[1:]:
            VICTIM.register(field).check(getattr(settings, field))
        settings.check()
        largest = delay_model.max_delay(settings.mode, length=self.length,
                                        mask_width=self.mask_width)
        if largest > MAX_TB_DELAY:
            raise ValueError(f"The testbench simulates delays up to {MAX_TB_DELAY} cycles; "
                             f"this source's delays reach {largest}: choose a shorter length or mask width")
        return settings

    def delays(self):
        """The delay of each pulse after the start, in cycles, as ``fliss sequence`` prints
        them (``--count pulses``)."""
        return [int(delay) for delay in self.settings().delays(self.pulses)]

    def max_delay(self):
        """The delay source's largest delay, in cycles."""
        settings = self.settings()
        return delay_model.max_delay(settings.mode, length=settings.length,
                                     mask_width=settings.mask_width)

    def command_bytes(self):
        """The UART bytes of a WRITE of the victim's delay source and a START, framed as a host
        frames them (:class:`~fliss.protocol.frames.PacketEncoder`, from sequence number 0)."""
        settings = self.settings()
        registers = [VICTIM.register(field) for field in _WRITTEN]
        addresses = [register.address for register in registers]
        assert addresses == list(range(addresses[0], addresses[0] + len(addresses)))
        values = [delay_model.parse_mode(settings.mode).value,
                  settings.length, settings.mask_width, settings.seed]
        encoder = PacketEncoder()
        payload = pack(registers_layout(len(values)), address=addresses[0], values=values)
        return encoder.frame(PacketType.WRITE, payload) + encoder.frame(PacketType.START)
