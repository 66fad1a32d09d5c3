"""FLISS on real boards: iCEBreaker (iCE40UP5K) and ULX3S (ECP5-85F).

* :mod:`.icebreaker`, :mod:`.ulx3s`: platforms on top of amaranth-boards, each with a PLL from the
  board oscillator to the design clock and the FLISS pin map on the PMOD (or GPIO) headers;
* :mod:`.build`: ``python -m fliss.boards.build BOARD``, bitstreams with the YoWASP tools, Fmax
  and utilisation from nextpnr, a non-zero exit when timing fails;
* :mod:`.constraints`: the constraints templates (PCF, LPF) of ``fliss generate``'s folder;
* :mod:`.netlist`, :mod:`.routed`: the builds' gate-level and routed netlists, for simulation;
* :mod:`.vendors`: ``python -m fliss.boards.vendors``, the generated Verilog synthesised for
  other vendors' FPGAs.

This module holds what both boards share and needs no board package: the pin names, the board
top level :class:`BoardTop` that puts any design on any of the boards, and the factories of the
designs the boards carry (:func:`fliss_top` and its variants).

The board modules need the ``boards`` extra (``pip install -e '.[boards]'``).
"""

import importlib

from amaranth.build import Resource
from amaranth.hdl import ClockDomain, ClockSignal, Elaboratable, Module, Signal
from amaranth.lib import io, wiring
from amaranth.lib.cdc import ResetSynchronizer
from amaranth.lib.wiring import In

from ..hdl.clock import DEFAULT_CLOCK_HZ


__all__ = ["BOARDS", "FLISS_PINS", "BOARD_PINS", "PIN_ALIASES", "PAD_SUFFIX", "pin_name", "pad_read_back",
           "platform_class", "BoardTop", "PllClocking", "FlissPlatform", "fliss_top",
           "fliss_top_fine", "fliss_top_spram", "fliss_top_up5k"]


#: Supported boards: name on the command line -> ``module:class`` of its platform.
BOARDS = {
    "icebreaker": "icebreaker:FlissICEBreakerPlatform",
    "ulx3s":      "ulx3s:FlissULX3SPlatform",
}

#: FLISS signals on the board headers: name -> (width, direction seen from the FPGA).
#: A design port with one of these names is wired to the pins of the same name.
FLISS_PINS = {
    "laser":     (1,  "o"),   # laser trigger of the victim
    "tdc_start": (1,  "o"),   # TDC start strobe, with the (delayed) laser pulse
    "aggressor": (1,  "o"),   # trigger of the aggressor's illuminator
    "timestamp": (13, "i"),   # sensor: TDC code, 50 ps LSB
    "address":   (6,  "i"),   # sensor: pixel address
    "valid":     (1,  "i"),   # sensor: event strobe
    "collision": (1,  "i"),   # sensor: collision flag
    "photon":    (1,  "i"),   # photon-hit input of the coarse and fine TDCs (SPAD module)
}

#: On-board signals: design port name -> (resource name, subsignal or None, width or None,
#: direction seen from the FPGA). ``led`` takes as many LEDs as the port is wide.
BOARD_PINS = {
    "uart_rx": ("uart",   "rx", 1,    "i"),   # from the on-board FTDI to the FPGA
    "uart_tx": ("uart",   "tx", 1,    "o"),   # from the FPGA to the on-board FTDI
    "button":  ("button", None, 1,    "i"),   # user button, high when pressed
    "led":     ("led",    None, None, "o"),   # on-board LEDs, lit when high
}


#: Other names a design may give a pin: alias -> name in :data:`FLISS_PINS`. Any name may also
#: carry a ``pin_`` prefix (``pin_timestamp``).
PIN_ALIASES = {
    "hit":              "photon",
    "photon_hit":       "photon",
    "aggressor_laser":  "aggressor",
    "sensor_timestamp": "timestamp",
    "sensor_address":   "address",
    "sensor_valid":     "valid",
    "sensor_collision": "collision",
    "running":          "led",
}


#: A design input named after an output of :data:`FLISS_PINS` (or an alias of one) with this
#: suffix reads that output's pad back (``laser_pad``, ``aggressor_laser_pad``).
PAD_SUFFIX = "_pad"


def pad_read_back(port_name):
    """The output of :data:`FLISS_PINS` whose pad a design port named ``port_name`` reads back
    (``"laser"`` for ``laser_pad``), or None."""
    if not port_name.endswith(PAD_SUFFIX):
        return None
    name = pin_name(port_name[:-len(PAD_SUFFIX)])
    return name if FLISS_PINS.get(name, (0, ""))[1] == "o" else None


def pin_name(port_name):
    """The name in :data:`FLISS_PINS` or :data:`BOARD_PINS` of the pins a design port named
    ``port_name`` is wired to (through a ``pin_`` prefix or :data:`PIN_ALIASES`), or the name
    itself if it is neither."""
    name = port_name[len("pin_"):] if port_name.startswith("pin_") else port_name
    name = PIN_ALIASES.get(name, name)
    return name if name in FLISS_PINS or name in BOARD_PINS else port_name


def platform_class(board):
    """The platform class of ``board`` (a key of :data:`BOARDS`), imported on demand."""
    try:
        spec = BOARDS[board]
    except KeyError:
        raise ValueError(f"Unknown board {board!r}; choose one of {', '.join(BOARDS)}") from None
    module_name, class_name = spec.split(":")
    module = importlib.import_module(f"{__name__}.{module_name}")
    return getattr(module, class_name)


class BoardTop(Elaboratable):
    """Board top level: clock, reset and pins around a design.

    The platform (a ``Fliss*Platform`` of this package) makes the ``sync`` domain from its PLL
    and reports the real frequency as ``platform.clock_hz``. The design is made by
    ``design(clock_hz)``, and must be a :class:`wiring.Component` whose ports are all plain
    signals. Each port is wired by name:

    * a name of :data:`FLISS_PINS` to the FLISS pins of the board;
    * a name of :data:`BOARD_PINS` to the on-board UART, button or LEDs;
    * the same with a ``pin_`` prefix, or an alias of :data:`PIN_ALIASES` (``hit``);
    * an input named after an output with :data:`PAD_SUFFIX` (``laser_pad``) to that output's
      pad as its input buffer reads it back: the output's buffer is then bidirectional, its
      output always enabled (the board's pins must allow it: the ULX3S's outputs do).

    Every input goes through a plain :class:`io.Buffer`: synchronising it is the design's job.
    Unwired inputs stay at their reset value; unwired outputs are left open. Both are listed in
    :attr:`unwired` after elaboration. A port whose width differs from its pins is an error.

    Parameters
    ----------
    design : callable
        ``design(clock_hz) -> wiring.Component``; :func:`fliss_top` by default.
    """

    def __init__(self, design=None):
        if design is None:
            design = fliss_top
        if not callable(design):
            raise TypeError(f"Design must be a callable that takes the clock frequency and "
                            f"returns a wiring.Component, not {design!r}")
        self._design = design
        self.unwired = []

    def elaborate(self, platform):
        m = Module()

        # Clock and reset: the domain is defined here, above the design, and driven by the
        # platform's PLL
        m.domains.sync = ClockDomain("sync")
        m.submodules.clocking = platform.clocking()

        # Design
        design = self._design(platform.clock_hz)
        if not isinstance(design, wiring.Component):
            raise TypeError(f"Design factory must return a wiring.Component, not {design!r}")
        m.submodules.design = design

        # Pins
        self.unwired = []
        ports = {}     # (resource, number) -> requested port
        buffers = {}   # pins -> their buffer

        def request(name, number):
            if (name, number) not in ports:
                ports[name, number] = platform.request(name, number, dir="-")
            return ports[name, number]

        # The pads read back: output pin name -> the design's input
        pads = {}
        for port_name, member in design.signature.members.items():
            if (name := pad_read_back(port_name)) is not None and member.is_port:
                if member.flow != In or len(getattr(design, port_name)) != 1:
                    raise ValueError(f"Port {port_name!r} of the design reads the {name} "
                                     f"pin's pad back: it must be an input of one bit")
                pads[name] = port_name

        for port_name, member in design.signature.members.items():
            if not member.is_port:
                raise TypeError(f"Port {port_name!r} of the design is an interface; the board "
                                f"top level wires plain signals only")
            port = getattr(design, port_name)
            if pad_read_back(port_name) is not None:
                continue        # (with its output, below)
            name = pin_name(port_name)
            width = len(port)
            direction = "i" if member.flow == In else "o"

            if name in FLISS_PINS:
                pins_width, pins_dir = FLISS_PINS[name]
                resource = platform.fliss_resource(name)
                key = (resource,)
                pins = [request(resource, 0)]
            elif name in BOARD_PINS:
                resource, subsignal, pins_width, pins_dir = BOARD_PINS[name]
                if pins_width is None:
                    pins_width = width
                    numbers = range(width)
                else:
                    numbers = [0]
                pins = [request(resource, n) for n in numbers]
                if subsignal is not None:
                    pins = [getattr(pin, subsignal) for pin in pins]
                key = (resource, subsignal, *numbers)
            else:
                self.unwired.append(port_name)
                continue

            if width != pins_width:
                raise ValueError(f"Port {port_name!r} of the design is {width} bits wide, but "
                                 f"its pins are {pins_width} bits wide")
            if direction != pins_dir:
                raise ValueError(f"Port {port_name!r} of the design is an "
                                 f"{'input' if direction == 'i' else 'output'}, but its pins "
                                 f"are {'inputs' if pins_dir == 'i' else 'outputs'}")

            if key in buffers:
                # Pins shared by two inputs (see `shared_pins` of the platform)
                assert direction == "i"
                buffer = buffers[key]
            elif name in pads:
                # An output read back: a bidirectional buffer, always driving
                pad_port = pads.pop(name)
                if pins[0].direction != io.Direction.Bidir:
                    raise ValueError(f"Port {pad_port!r} of the design reads the {name} pin's "
                                     f"pad back, but the board's {name} pin is an output only")
                buffer = io.Buffer("io", pins[0])
                m.submodules[f"{name}_buffer"] = buffers[key] = buffer
                m.d.comb += [buffer.oe.eq(1), getattr(design, pad_port).eq(buffer.i)]
            else:
                pin_io = pins[0] if len(pins) == 1 else _cat_ports(pins)
                buffer = io.Buffer(direction, pin_io)
                m.submodules[f"{name}_buffer"] = buffers[key] = buffer
            if direction == "i":
                m.d.comb += port.eq(buffer.i)
            else:
                m.d.comb += buffer.o.eq(port)
        if pads:
            name, pad_port = next(iter(pads.items()))
            raise ValueError(f"Port {pad_port!r} of the design reads the {name} pin's pad back, "
                             f"but the design has no {name} output")

        return m


def _cat_ports(ports):
    # Concatenate one-bit ports (for example one per LED) into one port, LSB first.
    result = ports[0]
    for port in ports[1:]:
        result = result + port
    return result


def fliss_top(clock_hz):
    """The FLISS top level (:class:`fliss.hdl.top.FlissTop`) at ``clock_hz``, for
    :class:`BoardTop`: histogram banks in block RAM."""
    from ..hdl.top import FlissTop
    return FlissTop(clock_hz=clock_hz)


def fliss_top_fine(clock_hz):
    """:func:`fliss_top` with the fine TDC (:mod:`fliss.hdl.finetdc`) on the photon pin: the
    ULX3S's design (an ECP5, whose carry chain makes the delay line)."""
    from ..hdl.top import FlissTop
    return FlissTop(clock_hz=clock_hz, fine_tdc=True)


def fliss_top_spram(clock_hz):
    """:func:`fliss_top` with the histogram banks in single-port RAM (the iCE40UP5K's SPRAM)."""
    from ..hdl.top import FlissTop
    return FlissTop(clock_hz=clock_hz, histogram_ram="single")


def fliss_top_up5k(clock_hz):
    """:func:`fliss_top` built to fit an iCE40UP5K (:data:`fliss.hdl.top.SMALL`): histograms
    only, their banks in its SPRAM; no aggressor emitter; narrower period and pulse width."""
    from ..hdl.top import FlissTop, SMALL
    return FlissTop(clock_hz=clock_hz, **SMALL)


def fliss_top_up5k_keyed(clock_hz):
    """:func:`fliss_top_up5k` with the keyed delay source, to measure whether it fits (it does
    not: see ``docs/boards.md``)."""
    from ..hdl.top import FlissTop, SMALL
    return FlissTop(clock_hz=clock_hz, **{**SMALL, "keyed": True})


class PllClocking(Elaboratable):
    """Shared tail of the board clocking: drives the ``sync`` domain (defined by
    :class:`BoardTop`) from the PLL output, and holds its reset until the PLL locks.

    Board platforms subclass it and fill in :meth:`pll`, which returns ``(clock, lock)``.
    Reset is held for ``hold_cycles`` after lock is seen (iCE40 block RAMs read as zero for a few
    microseconds after configuration).
    """

    hold_cycles = 1024

    def pll(self, m, platform):  # pragma: no cover - abstract
        raise NotImplementedError

    def elaborate(self, platform):
        m = Module()

        clock, lock = self.pll(m, platform)

        m.d.comb += ClockSignal("sync").eq(clock)
        # No net constraint here: nextpnr derives the PLL output's frequency from the divider
        # settings and the oscillator pin's constraint, and `fliss.boards.build` checks that the
        # derived constraint is the real clock.

        # Reset: asserted until lock, then held for `hold_cycles`
        m.domains.por = cd_por = ClockDomain("por", reset_less=False, local=True)
        m.d.comb += cd_por.clk.eq(clock)
        m.submodules.por_sync = ResetSynchronizer(~lock, domain="por")
        hold = Signal(range(self.hold_cycles + 1))
        ready = Signal()
        with m.If(hold == self.hold_cycles):
            m.d.por += ready.eq(1)
        with m.Else():
            m.d.por += hold.eq(hold + 1)
        m.submodules.sync_reset = ResetSynchronizer(~ready, domain="sync")

        return m


class FlissPlatform:
    """What the FLISS board platforms add to their amaranth-boards platform (put it first among
    the bases): a PLL to the design clock and one resource per FLISS pin.

    A board fills in:

    * :attr:`pins`: FLISS pin name -> pins on the board's headers, LSB first;
    * :attr:`shared_pins`: design ports that share the pins of another one, name -> name of the
      resource;
    * ``pll_search`` (a static method): ``(f_in_hz, f_out_hz)`` -> a PLL configuration with
      ``f_out_hz``, the real frequency;
    * ``fliss_io``: ``(pins, direction)`` -> ``(Pins, Attrs)`` of one FLISS signal;
    * ``clocking_class``: its :class:`PllClocking`;
    * :attr:`synth_opts`: options of its ``synth_<family>`` yosys command, if any;
    * :attr:`script_after_synth`: yosys commands after it, if any (every build of the platform
      runs them);
    * :attr:`nextpnr_opts`: options of its nextpnr command, if any, ahead of a caller's (every
      build of the platform runs with them).

    Parameters
    ----------
    clock_hz : int
        Wanted design clock; the PLL gets as close as it can, see :attr:`clock_hz`.

    Attributes
    ----------
    clock_hz : float
        The real design clock, in Hz.
    pll_config
        The PLL configuration that makes it.
    """

    pins = {}
    shared_pins = {}
    synth_opts = ()
    script_after_synth = ""
    nextpnr_opts = ()

    def __init__(self, *, clock_hz=DEFAULT_CLOCK_HZ, **kwargs):
        super().__init__(**kwargs)
        self.pll_config = self.pll_search(self.default_clk_frequency, clock_hz)
        self.clock_hz = self.pll_config.f_out_hz
        self.add_resources(self.fliss_resources())

    @classmethod
    def fliss_resources(cls):
        """The resources of the FLISS pins, ``fliss_<name>`` (number 0) for each name of
        :attr:`pins`."""
        resources = []
        for name, pins in cls.pins.items():
            width, direction = FLISS_PINS[name]
            ios, attrs = cls.fliss_io(pins, direction)
            assert len(ios.names) == width, name
            resources.append(Resource(f"fliss_{name}", 0, ios, attrs))
        return resources

    @classmethod
    def pin_map(cls):
        """The board's resources with the FLISS pins, for reading where each pin is (the
        constraints templates of :mod:`.constraints`): an instance of the board's own
        amaranth-boards platform, with no PLL search."""
        platform = cls.__new__(cls)
        super(FlissPlatform, platform).__init__()
        platform.add_resources(cls.fliss_resources())
        return platform

    def toolchain_prepare(self, fragment, name, **kwargs):
        # The board's own yosys commands after synthesis, unless the caller gives some; its own
        # nextpnr options ahead of the caller's
        if self.script_after_synth:
            kwargs.setdefault("script_after_synth", self.script_after_synth)
        if self.nextpnr_opts:
            given = kwargs.get("nextpnr_opts", ())
            given = given.split() if isinstance(given, str) else list(given)
            kwargs["nextpnr_opts"] = [*self.nextpnr_opts, *given]
        return super().toolchain_prepare(fragment, name, **kwargs)

    def fliss_resource(self, name):
        """Resource name of the FLISS pin ``name``."""
        return f"fliss_{self.shared_pins.get(name, name)}"

    def clocking(self):
        """Elaboratable that makes the ``sync`` domain at :attr:`clock_hz`."""
        return self.clocking_class()
