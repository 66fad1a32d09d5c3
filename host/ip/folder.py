"""The folder ``fliss generate`` writes: the top level as Verilog with everything a Verilog user
needs beside it."""

from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

from ... import __version__
from ...hdl.clock import cycle_units
from ...hdl.finetdc.tdc import BLACK_BOX_FILES
from ...hdl.registers import REGISTERS, VICTIM
from ...hdl.top import SMALL, FlissTop
from ...hdl.verilog import convert
from .core_file import core_text
from .ports_table import ports_table, top_ports


__all__ = ["Variant", "VARIANTS", "Generated", "MANIFEST", "check_build", "make_top",
           "victim_period", "write_folder"]


@dataclass(frozen=True)
class Variant:
    """A build ``fliss generate`` writes: the options of :class:`FlissTop`, what it is (a
    phrase), its design factory in :mod:`fliss.boards` and the flag that selects it."""
    options: dict
    what: str
    factory: str
    flag: str


#: The builds, by name.
VARIANTS = {
    "full":  Variant({}, "the whole instrument without the fine TDC", "fliss_top", ""),
    "small": Variant(SMALL, "the iCEBreaker's build: histograms only, no aggressor emitter, no "
                            "keyed delay source, no depth engine", "fliss_top_up5k", "--small"),
    "fine":  Variant({"fine_tdc": True}, "the whole instrument with the fine TDC, ECP5 only",
                     "fliss_top_fine", "--fine-tdc"),
}

#: The testbench: package data of this package, its file name.
_TESTBENCH = ("fliss.hdl.testbench", "fliss_top_tb.v")


class _Ecp5Cells:
    """What the fine TDC asks of a platform, to elaborate it with its ECP5 cells (the carry
    chain and the oscillator) and no build platform: the family, and the files it adds."""

    family = "ecp5"

    def __init__(self):
        self.extra_files = {}

    def add_file(self, name, content):
        self.extra_files[name] = content


@dataclass
class Generated:
    """What :func:`write_folder` wrote (``files``, the Verilog first), what it left out and
    why (``skipped``: one line each), and the files of an earlier ``fliss generate`` into the
    same folder that this one did not write and removed (``removed``)."""
    files: list = field(default_factory=list)
    skipped: list = field(default_factory=list)
    removed: list = field(default_factory=list)


#: The list of the files a ``fliss generate`` wrote into its folder, one relative path a line,
#: kept in that folder: the next one into the same folder removes the files of that list it does
#: not write again (an earlier build's testbench, a renamed module's Verilog), and only those.
MANIFEST = ".fliss-generated"


def _remove_stale(output, generated):
    # The files the manifest of an earlier run lists that this run did not write, then the
    # folders they leave empty (the folder itself stays). A manifest line that leaves the
    # folder is ignored: the list is a file anyone can edit.
    try:
        earlier = (output / MANIFEST).read_text().splitlines()
    except FileNotFoundError:
        return
    written = {path.relative_to(output).as_posix() for path in generated.files}
    root = output.resolve()
    for relative in earlier:
        path = output / relative
        if (not relative or relative in written or root not in path.resolve().parents
                or not path.is_file()):
            continue
        path.unlink()
        generated.removed.append(path)
        for parent in path.parents:
            if parent == output or any(parent.iterdir()):
                break
            parent.rmdir()


def make_top(variant, *, clock_hz, baud):
    """The :class:`FlissTop` of ``variant`` (a key of :data:`VARIANTS`); :exc:`ValueError` for
    a clock or baud rate it cannot have."""
    return FlissTop(clock_hz=clock_hz, baud=baud, **VARIANTS[variant].options)


def check_build(variant, *, name, clock_hz, testbench):
    """Refuse (:exc:`ValueError`), before a top level is made, a build of ``variant`` at
    ``clock_hz`` that cannot be made (the fine TDC's clock; a register whose reset value, a time
    in cycles, is out of its range), or a module name the folder uses for another module (the
    testbench's, with ``testbench``; the black boxes')."""
    if variant == "fine":
        cycle_units(clock_hz)
    for register in REGISTERS:
        value = register.reset_value(int(clock_hz))
        if not register.minimum <= value <= register.maximum:
            raise ValueError(f"At {clock_hz / 1e6:g} MHz register {register.name} would reset "
                             f"to {value}, beyond its range ({register.minimum} to "
                             f"{register.maximum}): choose a slower clock")
    taken = {"fliss_top_tb": testbench,
             **{cell: variant == "fine" for cell in ("FLISS_CCU2C", "OSCG")}}
    if taken.get(name):
        raise ValueError(f"--name: {name!r} is a module of the folder already; choose another "
                         f"module name")


def victim_period(clock_hz):
    """The victim's period after reset at ``clock_hz``, in cycles."""
    return VICTIM.register("period").reset_value(clock_hz)


def write_folder(output, top, *, name, variant, check=None):
    """Write ``top`` (a :class:`FlissTop` of ``variant``) as module ``name`` into the folder
    ``output``, with its core file, ports table, constraints templates, the black boxes of its
    vendor cells and, with ``check`` (a :class:`~.stimulus.DelayCheck`), the testbench.

    Returns :class:`Generated`; raises :exc:`ValueError` for bad settings of ``check`` and
    :exc:`OSError` when a file cannot be written.
    """
    output = Path(output)
    generated = Generated()
    check_build(variant, name=name, clock_hz=top.clock_hz, testbench=check is not None)
    if check is not None:
        delays = check.delays()                # (checked before the long conversion)

    def write(relative, text):
        path = output / relative
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
        generated.files.append(path)
        return relative

    # The Verilog, and the declarations of the vendor cells it instantiates
    fine = variant == "fine"
    verilog = write(f"{name}.v", convert(top, name, platform=_Ecp5Cells() if fine else None))
    black_boxes = [write(f"blackboxes/{file_name}", text)
                   for file_name, text in (BLACK_BOX_FILES if fine else ())]

    # The ports table, and the pins of each board for them
    ports = top_ports(top)
    what = VARIANTS[variant].what
    write("ports.md", f"# Ports of `{name}`\n\n{what[0].upper()}{what[1:]}; generated by FLISS "
                      f"{__version__} for a {top.clock_hz / 1e6:g} MHz clock.\n\n"
                      + ports_table(ports))
    _write_constraints(write, generated, ports, name=name, variant=variant,
                       clock_hz=top.clock_hz)

    # The testbench: its Verilog, the bytes it sends, the delays it expects
    testbench = None
    if check is not None:
        package, file_name = _TESTBENCH
        source = resources.files(package).joinpath(file_name).read_text()
        testbench = dict(
            file=write(f"testbench/{file_name}", source),
            data=[write("testbench/commands.hex",
                        "".join(f"{byte:02x}\n" for byte in check.command_bytes())),
                  write("testbench/expected_delays.hex",
                        "".join(f"{delay:x}\n" for delay in delays))],
            toplevel="fliss_top_tb",
            parameters=_tb_parameters(top, check),
            defines={"FLISS_TOP": (name, "the module under test"),
                     **({"FLISS_PADS": (True, "the fine TDC's pads read back")}
                        if fine else {})})
    write(f"{name}.core", core_text(
        module=name, version=__version__, verilog=verilog, black_boxes=black_boxes,
        testbench=testbench,
        description=f"FLISS top level, {VARIANTS[variant].what}; clock {top.clock_hz / 1e6:g} "
                    f"MHz, UART {top.baud} baud"))
    _remove_stale(output, generated)
    (output / MANIFEST).write_text(
        "".join(f"{path.relative_to(output).as_posix()}\n" for path in generated.files))
    return generated


def _tb_parameters(top, check):
    return {
        "CLOCK_HZ": (int(top.clock_hz), "clock of the top level, in Hz"),
        "BAUD": (int(top.baud), "its UART's baud rate"),
        "PERIOD": (check.period, "the victim's period after reset, in cycles"),
        "MAX_DELAY": (check.max_delay(), "the delay source's largest delay, in cycles"),
        "PULSES": (check.pulses, "pulses checked (delays in expected_delays.hex)"),
        "COMMAND_BYTES": (len(check.command_bytes()), "bytes in commands.hex"),
        "TIMESTAMP_BITS": (len(top.sensor_timestamp), "width of sensor_timestamp"),
        "ADDRESS_BITS": (len(top.sensor_address), "width of sensor_address"),
    }


def _write_constraints(write, generated, ports, *, name, variant, clock_hz):
    # A template per board that can carry the variant (the fine TDC's cells are ECP5 cells)
    from ...boards import BOARDS
    from ...boards.build import BOARD_DESIGN
    from ...boards.constraints import template_family, template_name, template_text
    for board in BOARDS:
        try:
            family = template_family(board)
        except ImportError:
            generated.skipped.append("constraints templates: they need amaranth-boards "
                                     "(pip install 'fliss[boards]')")
            return
        if variant == "fine" and family != "ecp5":
            generated.skipped.append(f"{board} constraints: the fine TDC needs an ECP5")
            continue
        own = BOARD_DESIGN[board].split(":")[1]
        flag = next((row.flag for row in VARIANTS.values() if row.factory == own), None)
        header = [f"Constraints template for {name} ({VARIANTS[variant].what}) on the {board}."]
        if own != VARIANTS[variant].factory:
            header.append(f"The board's own build is another one: fliss generate {flag}."
                          if flag is not None else f"The board's own build is {own}.")
        write(f"constraints/{template_name(board, name)}",
              template_text(board, ports, clock_hz, header=header))
