"""Dual-port bank storage of the histogram engine: block RAM, one event per cycle.

A bank of ``2**bank_bits`` bins spans many block RAMs (64 on the ULX3S's ECP5 for 65 536 bins),
spread over the whole chip: their words come back to the counting pipeline through registers
near each RAM and a registered OR tree, :data:`READ_STAGES` cycles more than one RAM would
take, and the pipeline forwards the counts of as many more events ahead. A bank of one block
(1024 words or fewer) has no read stages.
"""

from amaranth.hdl import Cat, Module, Mux, Signal
from amaranth.lib import wiring
from amaranth.lib.memory import Memory

from ..block_ram import RegisteredRam, has_dp16kd
from .banks import _MEMBERS_DOC, _increment, _members


__all__ = ["BLOCK_BITS", "READ_STAGES", "LATENCY", "read_stages", "latency", "forward",
           "DualPortBanks"]


#: Words of one RAM block of a bank, as a power of two: 1024 words of 16 bits, one ECP5 EBR.
BLOCK_BITS = 10
#: Registered stages between the RAM blocks' outputs and the bank's word, beyond the one that
#: a single RAM needs, in a bank of more than one block: the blocks' own registers, then one OR
#: level (groups of :data:`OR_GROUP`), then the word. A bank of one block has none.
READ_STAGES = 2
#: Inputs of each OR of the read tree's first level.
OR_GROUP = 4


def read_stages(bank_bits):
    """Read stages of a bank of ``2**bank_bits`` words: :data:`READ_STAGES` if it spans more
    than one block, else 0."""
    return READ_STAGES if bank_bits > BLOCK_BITS else 0


def latency(read_stages):
    """Cycles from an event's transfer on ``events`` to the block RAM write of its bin, in a
    bank of ``read_stages`` read stages (:func:`read_stages`)."""
    return 7 + read_stages


def forward(read_stages):
    """Events ahead whose writes a read misses (their counts are forwarded), in a bank of
    ``read_stages`` read stages (:func:`read_stages`)."""
    return 4 + read_stages


#: Most cycles from an event's transfer on ``events`` to the block RAM write of its bin (banks
#: of more than one block; :func:`latency` of :data:`READ_STAGES`).
LATENCY = latency(READ_STAGES)


class DualPortBanks(wiring.Component):
    __doc__ = """Two banks in block RAM (:class:`amaranth.lib.memory.Memory`), one event per cycle.

    Each bank is ``2**(bank_bits - 10)`` blocks of 1024 words (one block if smaller), every
    block a memory with a read port and a write port. The pipeline from the bin on: register the
    read address (R), the blocks' data out (D), each block's word registered near it (zero but
    in the block read: stage D1), OR-ed in groups (D2), the bank's word registered (Q) — the
    extra ``read_stages`` (:data:`READ_STAGES`, none with one block) cut the routing across the
    chip —, saturating increment with forwarding from the ``forward`` (:func:`forward`)
    events ahead (E), RAM write (W). ``word`` is the registered RAM word of the readout bank:
    ``read_stages`` cycles after the readout's CAPTURE, it holds until its next read. The
    readout's clearing write lands two cycles after its READ.

    The blocks and their read tree are built on an ECP5 (``DP16KD`` block RAM,
    :func:`~fliss.hdl.block_ram.has_dp16kd`), or with ``read_tree=True``. Elsewhere
    (``read_tree=None`` with no platform, as in simulation; or ``read_tree=False``) a bank of
    more than one block is one memory of ``2**bank_bits`` words whose word goes through as many
    registers, reset alike: the same word in the same cycle, without the per-block registers
    and the tree that a simulator would evaluate in every cycle (a quarter of Verilator's time
    on the top level).

    On a platform with a ``block_ram_quads`` floorplan (the ULX3S), each group of
    :data:`OR_GROUP` blocks sits in four neighbouring block RAM sites, so that the first level of
    the read tree is short; the groups of the two banks take turns in the platform's list.
""" + _MEMBERS_DOC

    def __init__(self, bank_bits, count_width, *, read_tree=None):
        if read_tree not in (None, False, True):
            raise TypeError(f"read_tree must be None, False or True, not {read_tree!r}")
        self.bank_bits = bank_bits
        self.count_width = count_width
        self.read_tree = read_tree
        self.read_stages = read_stages(bank_bits)
        #: Cycles from an event's transfer to the RAM write of its bin.
        self.latency = latency(self.read_stages)
        #: Events ahead whose writes a read misses (their counts are forwarded).
        self.forward = forward(self.read_stages)
        self.init_cycles = 0
        super().__init__(_members(bank_bits, count_width, initialising=False))
        self.block_bits = min(bank_bits, BLOCK_BITS)
        self.blocks = 1 << (bank_bits - self.block_bits)
        self.banks = tuple(_BlockedBank(self.block_bits, self.blocks, count_width,
                                        read_tree=read_tree)
                           for _ in range(2))

    def elaborate(self, platform):
        m = Module()

        width = self.bank_bits
        tree = has_dp16kd(platform) if self.read_tree is None else self.read_tree
        for k, bank in enumerate(self.banks):
            bank.tree = tree = tree or not bank.may_be_whole
            for j, memory in enumerate(bank.memories if tree else [bank.whole]):
                m.submodules[f"bank{k}_{j}"] = memory
        self._place(getattr(platform, "block_ram_quads", None) if tree else None)

        # Stage R: the bin (fine shift) is registered here and in the read address register of
        # its bank: the block RAMs sample it at the end of this cycle.
        valid_r = Signal()
        bin_r = Signal(width)
        bank_r = Signal()
        m.d.sync += [
            valid_r.eq(self.valid),
            bin_r.eq(self.bin),
            bank_r.eq(self.bank),
        ]

        # The stages after R, each a registered copy of the one before: D (data out), the read
        # stages, Q, E, W, and after W the events written one or more cycles ago.
        def stage(name, valid, bin, bank):
            copy = (Signal(name=f"valid_{name}"), Signal(width, name=f"bin_{name}"),
                    Signal(name=f"bank_{name}"))
            m.d.sync += [copy[0].eq(valid), copy[1].eq(bin), copy[2].eq(bank)]
            return copy

        stages = [stage("d", valid_r, bin_r, bank_r)]
        for n in range(self.read_stages):
            stages.append(stage(f"d{n + 1}", *stages[-1]))
        valid_q, bin_q, bank_q = stage("q", *stages[-1])
        valid_e, bin_e, bank_e = stage("e", valid_q, bin_q, bank_q)
        after = [stage("w", valid_e, bin_e, bank_e)]
        for n in range(self.forward - 3):
            after.append(stage(f"x{n + 1}", *after[-1]))   # written n + 1 cycles ago

        # A read misses the writes of the `forward` events ahead of it (written in its own cycle
        # or later). Their bins are compared with its own in the last stage before Q (`valid_p`
        # ...: event p), the outcome registered for stage Q.
        valid_p, bin_p, bank_p = stages[-1]
        ahead = [(valid_q, bin_q, bank_q), (valid_e, bin_e, bank_e)] + after
        hits_q = [Signal(name=f"hit{n + 1}_q") for n in range(self.forward)]
        m.d.sync += [hit.eq(valid_p & valid & (bin_p == bin) & (bank_p == bank))
                     for hit, (valid, bin, bank) in zip(hits_q, ahead)]

        # Stage Q: the bank's word (`stored`, from the read stages). `chain[n]` holds the count
        # written by the event n + 2 ahead; on a match the nearest replaces the stale word.
        stored = [bank.word for bank in self.banks]
        written = Signal(self.count_width)
        chain = [written] + [Signal(self.count_width, name=f"written_before{n + 1}")
                             for n in range(self.forward - 2)]
        base = Mux(bank_q, stored[1], stored[0])
        for hit, count in reversed(list(zip(hits_q[1:], chain))):
            base = Mux(hit, count, base)
        base_e = Signal(self.count_width)
        hit1_e = Signal()
        m.d.sync += [base_e.eq(base), hit1_e.eq(hits_q[0])]

        # Stage E: increment, saturating. `written` now holds the count of the event one ahead.
        # Both candidates are incremented side by side and the forwarding choice comes last, so
        # the loop through `written` is one increment and one LUT.
        new = Signal(self.count_width)
        m.d.comb += new.eq(Mux(hit1_e, _increment(m, written, self.count_width, "written"),
                               _increment(m, base_e, self.count_width, "base")))
        m.d.sync += [written.eq(new)]
        m.d.sync += [later.eq(earlier) for earlier, later in zip(chain, chain[1:])]

        # Stage W: the RAM write, from registers.

        # RAM ports, driven from registers: the pipeline uses the bank its event was tagged
        # with, the readout the other one. Each block has its own write enable register. The
        # readout's clearing write is registered once more before it is decoded to the blocks
        # (it lands a cycle later, while the readout still waits for its word).
        clear_index = Signal(width)
        m.d.sync += clear_index.eq(self.readout_index)
        for k, bank in enumerate(self.banks):
            read_address = Signal(width, name=f"read_address{k}")
            read_enable = Signal(name=f"read_enable{k}")
            write_address = Signal(width, name=f"write_address{k}")
            write_enable = Signal(name=f"write_enable{k}")
            write_data = Signal(self.count_width, name=f"write_data{k}")
            with m.If(self.valid & (self.bank == k)):
                m.d.sync += read_address.eq(self.bin), read_enable.eq(1)
            with m.Elif(self.readout_read & (self.readout_bank == k)):
                m.d.sync += read_address.eq(self.readout_index), read_enable.eq(1)
            with m.Else():
                m.d.sync += read_enable.eq(0)
            pipeline_write = valid_e & (bank_e == k)
            readout_write = Signal(name=f"clear{k}")
            m.d.sync += readout_write.eq(self.readout_clear & (self.readout_bank == k))
            write_to = Mux(pipeline_write, bin_e, clear_index)
            # (the data is a register of each bank's own, `written` or zero, as it goes to
            # every block of the bank, across the chip)
            with m.If(pipeline_write):
                m.d.sync += write_address.eq(bin_e), write_enable.eq(1), write_data.eq(new)
            with m.Elif(readout_write):
                m.d.sync += [write_address.eq(clear_index), write_enable.eq(1),
                             write_data.eq(0)]
            with m.Else():
                m.d.sync += write_enable.eq(0)
            bank.connect(m, read_address=read_address, read_enable=read_enable,
                         write_address=write_address, write_to=write_to,
                         write=pipeline_write | readout_write,
                         write_data=write_data)

        # The word of the bank being read out, from its registers
        m.d.comb += self.word.eq(Mux(self.readout_bank, stored[1], stored[0]))

        return m

    def _place(self, quads):
        # A platform that lists its block RAM sites in quads of four side by side, the best
        # first (`block_ram_quads`), has each group of the read tree in a quad, the two banks'
        # groups taking turns: a group's register then sits next to its blocks, and the banks
        # spread alike. (With fewer quads than groups, the placer decides.)
        if not all(bank.made for bank in self.banks):
            return                      # (one memory a bank: no blocks made)
        groups = [bank.memories[start:start + OR_GROUP] for start in range(0, self.blocks, OR_GROUP)
                  for bank in self.banks]
        for group in groups:
            for memory in group:
                memory.site = None
        if quads is None or self.blocks == 1 or len(groups) > len(quads):
            return
        for group, quad in zip(groups, quads):
            for memory, site in zip(group, quad):
                memory.site = site


class _BlockedBank:
    """One bank of :class:`DualPortBanks`: ``blocks`` memories of ``2**block_bits`` words, the
    read tree after them (``word``: the word read, ``read_stages(bank_bits)`` + 1 cycles after
    its address is sampled) and per-block write enables."""

    def __init__(self, block_bits, blocks, count_width, *, read_tree):
        self.block_bits = block_bits
        self.blocks = blocks
        self.count_width = count_width
        self._memories = None
        self._whole = None
        #: Whether the bank may be one memory (more than one block, ``read_tree`` not True).
        self.may_be_whole = blocks > 1 and read_tree is not True
        #: Whether the blocks and their read tree are built (set at elaboration).
        self.tree = True
        self.word = Signal(count_width)

    @property
    def whole(self):
        """The bank as one memory (``None`` if it may not be one), made when first asked for."""
        if self._whole is None and self.may_be_whole:
            self._whole = Memory(shape=self.count_width, depth=self.blocks << self.block_bits,
                                 init=[])
        return self._whole

    @property
    def data(self):
        """The bank's words, for testbenches: ``data[index]`` and ``data.depth``, as a
        :class:`~amaranth.hdl.MemoryData` (of the whole memory when the bank may be one: a
        simulation with ``read_tree=None``)."""
        if self.may_be_whole:
            return self.whole.data
        return _BankWords(self.memories, self.block_bits)

    @property
    def memories(self):
        """The blocks, made when first asked for (they are not made when the bank is one
        memory: a block made and not elaborated draws Amaranth's warning)."""
        if self._memories is None:
            if self.blocks == 1:
                self._memories = [Memory(shape=self.count_width, depth=1 << self.block_bits,
                                         init=[])]
            else:
                self._memories = [RegisteredRam(depth=1 << self.block_bits,
                                                width=self.count_width)
                                  for _ in range(self.blocks)]
        return self._memories

    @property
    def made(self):
        """Whether the blocks are made."""
        return self._memories is not None

    def connect(self, m, *, read_address, read_enable, write_address, write_to, write,
                write_data):
        low = self.block_bits
        blocks = self.blocks
        width = self.count_width
        # The block read, a cycle after its address is sampled (stage D); the groups of the OR
        # tree (D2) and the word (Q). Only the word holds between reads.
        read = [Signal(name=f"{self.word.name}_read_{stage}") for stage in ("d", "d1", "d2")]
        m.d.sync += [read[0].eq(read_enable)] + [b.eq(a) for a, b in zip(read, read[1:])]
        if blocks > 1 and not self.tree:
            self._connect_whole(m, read, read_address=read_address, read_enable=read_enable,
                                write_address=write_address, write=write,
                                write_data=write_data)
            return
        if blocks == 1:
            # one block: no read stages, its word registered as it leaves the RAM
            memory, = self.memories
            read_port = memory.read_port()
            write_port = memory.write_port()
            enable = Signal(name=f"{self.word.name}_write")
            m.d.sync += enable.eq(write)
            with m.If(read[0]):
                m.d.sync += self.word.eq(read_port.data)
            _wire_ports(m, read_port, write_port, read_address=read_address,
                        read_enable=read_enable, write_address=write_address, enable=enable,
                        write_data=write_data)
            return
        # More blocks: each a RegisteredRam, whose word is registered as it leaves the block
        # (stage D1: on the ECP5, the block RAM's own output register). Each block's select is
        # registered for D1 (one-hot over the blocks), and the groups of the OR tree take the
        # words of their blocks AND-ed with their selects (D2).
        block_d = Signal(len(read_address) - low, name=f"{self.word.name}_block_d")
        m.d.sync += block_d.eq(read_address[low:])
        words = []
        for j, memory in enumerate(self.memories):
            chosen = Signal(name=f"{self.word.name}_chosen{j}")
            enable = Signal(name=f"{self.word.name}_write{j}")
            # (each block's write enable is a register of its own, loaded with the address)
            m.d.sync += [
                chosen.eq(read[0] & (block_d == j)),
                enable.eq(write & (write_to[low:] == j)),
            ]
            m.d.comb += [
                memory.read_addr.eq(read_address[:low]),
                memory.read_en.eq(read_enable),
                memory.write_addr.eq(write_address[:low]),
                memory.write_en.eq(enable),
                memory.write_data.eq(write_data),
            ]
            words.append(memory.read_data & chosen.replicate(width))
        # the OR tree: groups registered, then the word (held between reads)
        groups = []
        for start in range(0, blocks, OR_GROUP):
            group = Signal(width, name=f"{self.word.name}_group{start // OR_GROUP}")
            part = words[start:start + OR_GROUP]
            m.d.sync += group.eq(Cat(*[Cat(w[bit] for w in part).any() for bit in range(width)])
                                 if len(part) > 1 else part[0])
            groups.append(group)
        with m.If(read[2]):
            m.d.sync += self.word.eq(
                Cat(*[Cat(g[bit] for g in groups).any() for bit in range(width)])
                if len(groups) > 1 else groups[0])


    def _connect_whole(self, m, read, *, read_address, read_enable, write_address, write,
                       write_data):
        # The bank as one memory: its word registered twice (the blocks' registers, the
        # groups) and then held as the tree's (Q), so it comes out in the same cycle; the
        # write enable registered as each block's is (the address and data are registers).
        read_port = self.whole.read_port()
        write_port = self.whole.write_port()
        out = [Signal(self.count_width, name=f"{self.word.name}_out_{stage}")
               for stage in ("d1", "d2")]
        enable = Signal(name=f"{self.word.name}_write")
        m.d.sync += [out[0].eq(read_port.data), out[1].eq(out[0]), enable.eq(write)]
        with m.If(read[2]):
            m.d.sync += self.word.eq(out[1])
        _wire_ports(m, read_port, write_port, read_address=read_address,
                    read_enable=read_enable, write_address=write_address, enable=enable,
                    write_data=write_data)


def _wire_ports(m, read_port, write_port, *, read_address, read_enable, write_address, enable,
                write_data):
    # A memory's read and write ports, as a bank of one memory drives them.
    m.d.comb += [
        read_port.addr.eq(read_address),
        read_port.en.eq(read_enable),
        write_port.addr.eq(write_address),
        write_port.en.eq(enable),
        write_port.data.eq(write_data),
    ]


class _BankWords:
    """The words of a :class:`_BlockedBank`, indexed as one memory."""

    def __init__(self, memories, block_bits):
        self._memories = memories
        self._block_bits = block_bits
        self.depth = len(memories) << block_bits

    def __getitem__(self, index):
        return self._memories[index >> self._block_bits].data[index & ((1 << self._block_bits) - 1)]
