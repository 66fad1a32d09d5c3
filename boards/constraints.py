"""Constraints templates: the pins of each board for the ports of a top level as ``fliss generate``
writes it, as a PCF (iCE40, nextpnr-ice40) or an LPF (ECP5, nextpnr-ecp5 and Diamond).

The pins come from the boards' own definitions, as their bitstream builds use them: the FLISS
pins of each platform (:attr:`~fliss.boards.FlissPlatform.pins` and its ``fliss_io``) and the
on-board UART, LEDs and oscillator of amaranth-boards, wired to a port by name as
:class:`~fliss.boards.BoardTop` wires them (:func:`~fliss.boards.pin_name`).

A template constrains the generated module as if it were the top level of the FPGA. Ports no
pin drives directly are comments that say why: ``clk`` (the board's oscillator, through a PLL to
the generated clock), ``rst`` (the design's reset logic), a pad read back (a bidirectional
buffer in the design), a port that shares its pin with another one.

Needs amaranth-boards (the ``boards`` extra).
"""

from dataclasses import dataclass, field

from . import BOARD_PINS, FLISS_PINS, pad_read_back, pin_name, platform_class


__all__ = ["PinRow", "pin_rows", "template_family", "template_text", "template_name"]


@dataclass(frozen=True)
class PinRow:
    """One bit of a port on a board: ``pin`` the package pin (None: no pin), ``attrs`` its I/O
    attributes, ``note`` why the row is a comment ("" for a pin constraint)."""
    port: str
    bit: object
    pin: object
    attrs: dict = field(default_factory=dict)
    note: str = ""

    @property
    def net(self):
        """The port bit's name in a constraints file: ``port`` or ``port[bit]``."""
        return self.port if self.bit is None else f"{self.port}[{self.bit}]"


def _bits(port, width, pins, note=""):
    # Rows of a port of `width` bits on `pins` (a list of PortMetadata, LSB first)
    return [PinRow(port, None if width == 1 else bit, meta.name, dict(meta.attrs), note)
            for bit, meta in enumerate(pins)]


def pin_rows(board, ports, clock_hz):
    """The platform of ``board`` (a key of :data:`~fliss.boards.BOARDS`) and the rows of
    ``ports`` (``(name, "in" or "out", width)`` of the top level, in order) on it, whose design
    clock is ``clock_hz``."""
    platform = platform_class(board).pin_map()
    rows = {}
    groups = {}     # resource with subsignals -> its requested port group
    shared = []     # ports on the pins of another one, after the others
    for name, direction, width in ports:
        wanted = "i" if direction == "in" else "o"
        pins = pin_name(name)
        if name == "clk":
            meta = platform.request(platform.default_clk, 0, dir="-").io.metadata
            oscillator = platform.default_clk_frequency
            note = (f"the board's {oscillator / 1e6:g} MHz oscillator: through a PLL to "
                    f"{clock_hz / 1e6:g} MHz" if oscillator != clock_hz else "")
            rows[name] = _bits(name, width, meta, note)
        elif name == "rst":
            rows[name] = [PinRow(name, None, None, note="no pin: from your reset logic (held "
                                 "until the PLL locks, released synchronously to clk)")]
        elif (output := pad_read_back(name)) is not None:
            rows[name] = [PinRow(name, None, None, note=f"no pin: the {output} pin's pad read "
                                 f"back (a bidirectional buffer, its output always enabled)")]
        elif pins in FLISS_PINS:
            _check(board, name, width, wanted, FLISS_PINS[pins])
            if pins in platform.shared_pins:
                shared.append((name, pins))
                rows[name] = None
            else:
                resource = platform.fliss_resource(pins)
                rows[name] = _bits(name, width,
                                   platform.request(resource, 0, dir="-").io.metadata)
        elif pins in BOARD_PINS:
            resource, subsignal, pins_width, pins_dir = BOARD_PINS[pins]
            _check(board, name, width, wanted, (pins_width or width, pins_dir))
            if subsignal is None:
                meta = [platform.request(resource, n, dir="-").io.metadata[0]
                        for n in range(width)]
            else:
                if resource not in groups:
                    groups[resource] = platform.request(resource, 0, dir="-")
                meta = getattr(groups[resource], subsignal).io.metadata
            rows[name] = _bits(name, width, meta)
        else:
            rows[name] = [PinRow(name, None, None, note="no pin on this board")]
    # A port on the pins of another one: the same pins, as a comment
    for name, pins in shared:
        owner = next(port for port, _, _ in ports
                     if pin_name(port) == platform.shared_pins[pins])
        rows[name] = [PinRow(name, row.bit, row.pin, row.attrs,
                             f"shares the pin of {owner}: wire one of the two")
                      for row in rows[owner]]
    return platform, [row for name, _, _ in ports for row in rows[name]]


def _check(board, name, width, direction, pins):
    pins_width, pins_dir = pins
    if (width, direction) != (pins_width, pins_dir):
        raise ValueError(f"Port {name!r} ({width} bits, {direction}) does not fit its pins on "
                         f"the {board} ({pins_width} bits, {pins_dir})")


def template_name(board, module):
    """File name of ``board``'s template for ``module``: ``<module>_<board>.pcf`` or ``.lpf``."""
    return f"{module}_{board}.{_format(board)}"


#: The constraints file of each FPGA family (an amaranth platform's ``family``).
_FORMATS = {"ice40": "pcf", "ecp5": "lpf"}


def template_family(board):
    """The FPGA family of ``board`` (``"ice40"``, ``"ecp5"``); :exc:`ImportError` without
    amaranth-boards."""
    return platform_class(board).pin_map().family.lower()


def _format(board):
    return _FORMATS[template_family(board)]


def template_text(board, ports, clock_hz, header=()):
    """The constraints template of ``ports`` on ``board`` (see :func:`pin_rows`), its first lines
    the comment lines of ``header``."""
    platform, rows = pin_rows(board, ports, clock_hz)
    kind = _FORMATS[platform.family.lower()]
    lines = [f"# {line}".rstrip() for line in header]
    lines.append(f"# Pins of the {board} ({platform.device}-{platform.package}), from the "
                 f"FLISS board definitions (fliss.boards).")
    for row in rows:
        lines += _pcf(row) if kind == "pcf" else _lpf(row)
    if kind == "lpf":
        frequency = f"{clock_hz / 1e6:g} MHZ;"
        on_pin = any(row.port == "clk" and row.pin and not row.note for row in rows)
        lines.append(f'FREQUENCY PORT "clk" {frequency}' if on_pin else
                     f'# the clock from the PLL: FREQUENCY NET "<its net>" {frequency}')
    return "\n".join(lines) + "\n"


def _pcf(row):
    if row.pin is None:
        return [f"# {row.net}: {row.note}"]
    constraint = f"set_io {row.net} {row.pin}"
    return [f"# {row.net}: {row.note}", f"# {constraint}"] if row.note else [constraint]


def _lpf(row):
    if row.pin is None:
        return [f"# {row.net}: {row.note}"]
    attrs = " ".join(f"{key}={value}" for key, value in row.attrs.items()
                     if isinstance(value, str))
    constraint = [f'LOCATE COMP "{row.net}" SITE "{row.pin}";']
    if attrs:
        constraint.append(f'IOBUF PORT "{row.net}" {attrs};')
    if row.note:
        return [f"# {row.net}: {row.note}"] + [f"# {line}" for line in constraint]
    return constraint
