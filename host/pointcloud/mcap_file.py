"""Points to MCAP for Foxglove: one ``foxglove.PointCloud`` message (protobuf, the schema
Foxglove publishes, from ``foxglove-schemas-protobuf``) per depth frame (:mod:`.mcap_frames`),
so that Foxglove plays a capture frame by frame. Each message holds every field of
:data:`~.points.POINT_DTYPE` as a packed field."""

from .mcap_frames import FRAME_ID, TOPIC, FrameMessages
from .points import POINT_DTYPE


__all__ = ["McapWriter", "TOPIC", "FRAME_ID"]


def _descriptor_set(descriptor):
    # The FileDescriptorSet of a message type: its file and every file it imports, imports
    # first (what a protobuf schema in MCAP holds)
    from google.protobuf.descriptor_pb2 import FileDescriptorSet

    files, seen = [], set()

    def add(file):
        if file.name in seen:
            return
        seen.add(file.name)
        for dependency in file.dependencies:
            add(dependency)
        files.append(file)

    add(descriptor.file)
    result = FileDescriptorSet()
    for file in files:
        file.CopyToProto(result.file.add())
    return result.SerializeToString()


class McapWriter(FrameMessages):
    """Writes ``total`` points to ``path``, a ``foxglove.PointCloud`` per frame: :meth:`write`
    each run (whole frames), then :meth:`close`. ``comments`` go to the file's ``fliss``
    metadata record."""

    def channel(self, writer):
        from foxglove_schemas_protobuf.PackedElementField_pb2 import PackedElementField
        from foxglove_schemas_protobuf.PointCloud_pb2 import PointCloud

        types = {"<f4": PackedElementField.FLOAT32, "<f8": PackedElementField.FLOAT64,
                 "<u4": PackedElementField.UINT32, "<u2": PackedElementField.UINT16}
        self._type = PointCloud
        self._fields = [PackedElementField(name=name, offset=POINT_DTYPE.fields[name][1],
                                           type=types[POINT_DTYPE.fields[name][0].str])
                        for name in POINT_DTYPE.names]
        schema = writer.register_schema(name=PointCloud.DESCRIPTOR.full_name,
                                        encoding="protobuf",
                                        data=_descriptor_set(PointCloud.DESCRIPTOR))
        return writer.register_channel(topic=TOPIC, message_encoding="protobuf",
                                       schema_id=schema)

    def message(self, points, nanoseconds):
        # A message a frame (the protobuf runtime frees a message's memory with the message:
        # one message reused would keep every frame's points until the end)
        message = self._type(frame_id=FRAME_ID, point_stride=POINT_DTYPE.itemsize,
                             fields=self._fields, data=points.tobytes())
        message.timestamp.FromNanoseconds(nanoseconds)
        message.pose.orientation.w = 1.0
        return message.SerializeToString()
