"""The FuseSoC core file (CAPI2) of a folder that ``fliss generate`` writes: the Verilog, the
black boxes it needs and the testbench as filesets; targets ``lint`` (Verilator, lint only) and
``sim`` (Icarus, the testbench)."""

import json


__all__ = ["core_name", "core_text"]


def _quoted(text):
    # A YAML double-quoted scalar (a JSON string is one)
    return json.dumps(text)


def core_name(module, version):
    """The core's VLNV: ``fliss:fliss:<module>:<version>``."""
    return f"fliss:fliss:{module}:{version}"


#: Verilator's lint warnings the Verilog of Yosys (``write_verilog``) gives by construction,
#: waived (any other warning fails the lint): constants narrower or wider than the operand they
#: meet, and the one-hot ``casez`` of its ``parallel_case`` multiplexers.
_LINT_WAIVERS = (
    "# Yosys's Verilog: constants of another width than their operand; its parallel_case",
    "# multiplexers' casez patterns overlap by construction (one-hot selects)",
    "verilator_options: [-Wno-WIDTHEXPAND, -Wno-WIDTHTRUNC, -Wno-CASEOVERLAP]",
)


def _files(paths, indent="      "):
    return [f"{indent}- {path}" for path in paths]


def core_text(*, module, version, verilog, black_boxes=(), testbench=None, description=""):
    """CAPI2 text of ``module`` (its Verilog file ``verilog``, the files ``black_boxes``).

    ``testbench`` is None (no ``sim`` target) or a dict: ``file`` (the testbench), ``data``
    (files the simulation reads from its working folder), ``toplevel``, ``parameters``
    (name -> ``(value, description)``, Verilog parameters of the testbench) and ``defines``
    (name -> ``(value, description)``).
    """
    lines = ["CAPI=2:", "", f"name: {core_name(module, version)}",
             f"description: {_quoted(description)}", "", "filesets:",
             "  rtl:", "    files:", *_files([verilog]), "    file_type: verilogSource"]
    lint_sets = ["rtl"]
    if black_boxes:
        lines += ["  blackboxes:", "    files:", *_files(black_boxes),
                  "    file_type: verilogSource"]
        lint_sets.append("blackboxes")
    if testbench is not None:
        lines += ["  tb:", "    files:",
                  f"      - {testbench['file']}: {{file_type: verilogSource}}"]
        lines += [f"      - {path}: {{file_type: user, copyto: {path.rsplit('/', 1)[-1]}}}"
                  for path in testbench["data"]]
    lines += ["", "targets:",
              "  default:", "    filesets: [rtl]", f"    toplevel: {module}",
              "  lint:", "    default_tool: verilator", f"    filesets: [{', '.join(lint_sets)}]",
              f"    toplevel: {module}", "    tools:", "      verilator:",
              "        mode: lint-only",
              *(f"        {line}" for line in _LINT_WAIVERS)]
    if testbench is not None:
        names = [*testbench["parameters"], *testbench["defines"]]
        lines += ["  sim:", "    default_tool: icarus",
                  f"    filesets: [{', '.join(lint_sets + ['tb'])}]",
                  f"    toplevel: {testbench['toplevel']}",
                  f"    parameters: [{', '.join(names)}]",
                  "    tools:", "      icarus:", "        iverilog_options: [-g2012]",
                  "", "parameters:"]
        for kinds, datatype_of in ((testbench["parameters"], "vlogparam"),
                                   (testbench["defines"], "vlogdefine")):
            for name, (value, text) in kinds.items():
                datatype = "int" if isinstance(value, int) and not isinstance(value, bool) \
                    else "bool" if isinstance(value, bool) else "str"
                shown = str(value).lower() if isinstance(value, bool) else value
                lines += [f"  {name}:", f"    datatype: {datatype}",
                          f"    paramtype: {datatype_of}", f"    default: {shown}",
                          f"    description: {_quoted(text)}"]
    return "\n".join(lines) + "\n"
