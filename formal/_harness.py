"""Helpers of the link and histogram harnesses: internal signals of a block, past values,
and mutants made by overriding a block's own statements."""

from amaranth.hdl import Module, Signal
from amaranth.hdl._ast import Assign, Switch

from .runner import assigned_signals


def past(m, value, cycles=1, *, name="past"):
    """``value`` ``cycles`` cycles ago (its initial value before that)."""
    for _ in range(cycles):
        delayed = Signal.like(value, name=name)
        m.d.sync += delayed.eq(value)
        value = delayed
    return value


def assigned(module, *names):
    """The signals named ``names`` that the elaborated ``module`` (a :class:`Module`, not yet a
    fragment) assigns, in that order; for invariants about its state and for mutants."""
    module._flush()         # (close the block's last `If` chain, or it is not in the list)
    found = assigned_signals(module._statements.values())
    for name, generated in module._generated.items():
        state = getattr(generated, "state", None)       # an FSM's state: `<name>_state`
        if state is not None:
            found.setdefault(f"{name}_state", state)
    missing = [name for name in names if name not in found]
    if missing:
        raise KeyError(f"No signal {', '.join(missing)} in {type(module).__name__}")
    return [found[name] for name in names]


def open_block(block, mutate=None, platform=None):
    """Elaborate ``block`` into its :class:`Module` (to add as a submodule in its place), whose
    signals :func:`assigned` finds; ``mutate(block, module)`` may then add statements that
    override the block's own (a mutant)."""
    block._MustUse__silence = True      # (elaborated here, not by the converter)
    module = block.elaborate(platform)
    if not isinstance(module, Module):
        raise TypeError(f"{type(block).__name__} does not elaborate into a Module")
    if mutate is not None:
        mutate(block, module)
    return module


def open_submodule(module, name, mutate=None, platform=None):
    """Elaborate the submodule ``name`` of ``module`` in place (:func:`open_block`); returns
    the block and its module."""
    block, src_loc = module._named_submodules[name]
    inner = open_block(block, mutate, platform)
    module._named_submodules[name] = (inner, src_loc)
    return block, inner


def fsm(module, name="fsm"):
    """The state signal of the FSM ``name`` of ``module`` and a function of a state's name that
    tests for it."""
    machine = module._generated[name]
    return machine.state, lambda *states: machine.state.matches(
        *(machine.encoding[state] for state in states))


def copy_of(module, source):
    """The signal of ``module`` that a statement ``signal.eq(source)`` assigns (a pipeline
    register after ``source``, however it is named)."""
    module._flush()

    def walk(statements):
        for statement in statements:
            if isinstance(statement, Assign) and statement.rhs is source:
                return statement.lhs
            if isinstance(statement, Switch):
                for case in statement.cases:
                    found = walk(case[1] if isinstance(case, tuple) else statement.cases[case])
                    if found is not None:
                        return found
        return None

    for statements in module._statements.values():
        found = walk(statements)
        if found is not None:
            return found
    raise KeyError(f"No copy of {source.name} in {type(module).__name__}")
