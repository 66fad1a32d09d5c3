"""The ports table of a top level: each port's name, direction, width and meaning, as Markdown."""

from amaranth.lib.wiring import In

from ...hdl.ports import CLOCK_PORTS, PORT_MEANINGS


__all__ = ["HEADER", "top_ports", "ports_table"]


#: The table's header row and rule.
HEADER = ("| port | direction | width | meaning |", "| --- | --- | --- | --- |")


def top_ports(component):
    """``(name, "in" or "out", width)`` of each port of ``component``'s Verilog module, in
    order: the clock and reset Verilog conversion adds, then the component's signature."""
    ports = list(CLOCK_PORTS)
    for name, member in component.signature.members.items():
        ports.append((name, "in" if member.flow == In else "out",
                      len(getattr(component, name))))
    return ports


def ports_table(ports):
    """The Markdown table of ``ports`` (as :func:`top_ports` gives them), one row each."""
    rows = list(HEADER)
    for name, direction, width in ports:
        if name not in PORT_MEANINGS:
            raise ValueError(f"Port {name!r} has no meaning in fliss.hdl.ports.PORT_MEANINGS")
        rows.append(f"| `{name}` | {direction} | {width} | {PORT_MEANINGS[name]} |")
    return "\n".join(rows) + "\n"
