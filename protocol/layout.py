"""Payloads from and to the values of their :mod:`amaranth.lib.data` layouts.

A payload's bytes are the layout's value (``Identity``, ``Status``, ``Nak``, ...) as the gateware's
``as_value()`` gives it, little-endian and rounded up to whole bytes: :func:`pack`,
:func:`unpack`, :func:`unpack_from`, :func:`byte_size`. Arrays of registers or counts are
little-endian words: :func:`pack_words`, :func:`unpack_words`.
"""

import enum
from collections.abc import Mapping

import numpy as np
from amaranth.hdl import Shape
from amaranth.lib import data

from ..hdl.protocol import REGISTER_BITS


__all__ = ["byte_size", "pack", "unpack", "unpack_from", "word_dtype", "pack_words",
           "unpack_words"]


def byte_size(layout):
    """Bytes of a payload of ``layout`` (a :class:`amaranth.lib.data.Layout` or a
    :class:`~amaranth.lib.data.Struct`), its bits rounded up to whole bytes."""
    return _layout(layout)[0]


def _writer(shape, name):
    # A function from the values of ``shape`` to its bits, with the fields looked up once.
    if isinstance(shape, data.StructLayout):
        fields = [(field_name, field.offset, _writer(field.shape, f"{name}.{field_name}"))
                  for field_name, field in shape]
        names = {field_name for field_name, _, _ in fields}

        def write_struct(value):
            if not isinstance(value, Mapping):
                raise TypeError(f"Value of {name} must be a mapping of field names, not "
                                f"{value!r}")
            if not names.issuperset(value):
                raise ValueError(f"{name} has no field {sorted(set(value) - names)[0]!r}")
            return sum(write(value[field_name]) << offset
                       for field_name, offset, write in fields if field_name in value)
        return write_struct
    if isinstance(shape, data.ArrayLayout):
        elements = [(field.offset, _writer(field.shape, f"{name}[{index}]"))
                    for index, field in shape]

        def write_array(value):
            if len(value) != len(elements):
                raise ValueError(f"{name} needs {len(elements)} elements, not {len(value)}")
            return sum(write(item) << offset for (offset, write), item in zip(elements, value))
        return write_array
    width = Shape.cast(shape).width

    def write_field(value):
        value = value.value if isinstance(value, enum.Enum) else int(value)
        if value < 0 or value >> width:
            raise ValueError(f"{name} = {value} does not fit in {width} bits")
        return value
    return write_field


def _reader(shape):
    # A function from the bits of ``shape`` to its values, with the fields looked up once.
    if isinstance(shape, (data.StructLayout, data.ArrayLayout)):
        fields = [(name, field.offset, (1 << field.width) - 1, _reader(field.shape))
                  for name, field in shape]
        if isinstance(shape, data.ArrayLayout):
            return lambda bits: [read((bits >> offset) & mask) for _, offset, mask, read in fields]
        return lambda bits: {name: read((bits >> offset) & mask)
                             for name, offset, mask, read in fields}
    return int


def pack(layout, values=None, /, **fields):
    """The payload bytes of ``layout`` with ``values`` (a dict of field names, lists for
    arrays, nested as the layout is) or keyword ``fields``: the little-endian image of the
    layout's value, as the gateware sends ``as_value()``. Fields left out are zero; enum
    members may stand for their values. Raises :exc:`ValueError` for a value that does not fit
    its field."""
    size, _, write = _layout(layout)
    return write({**(values or {}), **fields}).to_bytes(size, "little")


def _layout(layout):
    # Size in bytes, reader and writer of a layout, made once per layout (a header is read and
    # written per packet).
    try:
        return _LAYOUTS[layout]
    except KeyError:
        cast = data.Layout.cast(layout)
        _LAYOUTS[layout] = result = \
            (cast.size + 7) // 8, _reader(cast), _writer(cast, "payload")
        return result


_LAYOUTS = {}


def unpack_from(layout, payload, offset=0):
    """The values of ``layout`` (a dict, nested as the layout, arrays as lists, enum fields as
    their integers) read from ``payload`` at byte ``offset``; bytes after it are ignored."""
    size, read, _ = _layout(layout)
    chunk = bytes(payload[offset:offset + size])
    if len(chunk) != size:
        raise ValueError(f"Payload of {len(payload)} bytes is too short for {size} bytes at "
                         f"offset {offset}")
    return read(int.from_bytes(chunk, "little"))


def unpack(layout, payload):
    """The values of ``layout`` in ``payload``, which must be exactly as long as the layout (see
    :func:`unpack_from`)."""
    if len(payload) != byte_size(layout):
        raise ValueError(f"Payload of {len(payload)} bytes, not {byte_size(layout)}")
    return unpack_from(layout, payload)


def word_dtype(width=REGISTER_BITS):
    """numpy dtype of little-endian unsigned ``width``-bit words (8, 16 or 32)."""
    return np.dtype(f"<u{width // 8}")


def pack_words(words, width=REGISTER_BITS):
    """Little-endian ``width``-bit words (u32 by default), one after the other; raises
    :exc:`ValueError` for a word that does not fit."""
    values = np.asarray(words, dtype=object if not isinstance(words, np.ndarray) else None)
    if values.size and (values.min() < 0 or int(values.max()) >> width):
        raise ValueError(f"Words must be from 0 to {(1 << width) - 1}")
    return values.astype(word_dtype(width)).tobytes()


def unpack_words(payload, width=REGISTER_BITS, offset=0):
    """The little-endian ``width``-bit words (u32 by default) of ``payload`` from byte
    ``offset`` to its end, as a list of ints."""
    dtype = word_dtype(width)
    if (len(payload) - offset) % dtype.itemsize:
        raise ValueError(f"{len(payload) - offset} bytes are not a whole number of "
                         f"{dtype.itemsize}-byte words")
    return np.frombuffer(bytes(payload), dtype=dtype, offset=offset).tolist()
