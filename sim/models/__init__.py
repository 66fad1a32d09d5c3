"""Bit-exact reference models of the gateware's blocks, one module per block (``fliss.hdl``):
:mod:`.lfsr`, :mod:`.trivium`, :mod:`.delay`, :mod:`.scheduler`, :mod:`.aggressor`,
:mod:`.tdc`, :mod:`.finetdc`, :mod:`.rawfifo`, :mod:`.histogram`, :mod:`.depth`, :mod:`.uart`,
:mod:`.command`.
"""
