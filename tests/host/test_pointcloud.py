"""Depth frames out as point clouds, read back by readers FLISS does not write with: plyfile
(PLY), pypcd4 (PCD), this file's own decoder of the LAS 1.4 specification beside laspy (LAS),
and the mcap reader with the protobuf schema it carries (MCAP). Each point is checked against
the capture's depths placed by trigonometry worked out here, not by the exporter's code."""

import math
import struct

import h5py
import numpy as np
import pytest

from fliss.host.kinds.depth import append as append_depth, create as create_depth
from fliss.host.pointcloud.export import WRITERS, export_points
from fliss.host.pointcloud import points as points_module
from fliss.host.pointcloud.geometry import SensorGeometry
from fliss.host.stream import DepthFrame


PIXELS = 16
CODE_S = 50e-12
SHIFT = 4
FRAMES = 11
#: A column of 16 pixels from address 8, 30 µm pitch, a 2.5 mm lens.
GEOMETRY = SensorGeometry(columns=1, pitch_m=30e-6, focal_m=2.5e-3)


@pytest.fixture(scope="module")
def capture(tmp_path_factory):
    """A depth capture of 11 frames, some pixels undetected, frame 5 never arrived."""
    path = tmp_path_factory.mktemp("depth") / "depth.h5"
    generator = np.random.default_rng(7)
    configuration = {"pixel_bits": 4, "first_pixel": 8, "bin_shift": SHIFT}
    with h5py.File(path, "w") as f:
        f.attrs["mode"] = "depth"
        pixels = create_depth(f, configuration, CODE_S)
        for index in range(FRAMES):
            detected = generator.random(PIXELS) < 0.7
            position = np.where(detected, generator.uniform(10, 400, PIXELS), np.nan)
            frame = DepthFrame(1000 + index, 8, SHIFT, position,
                               generator.uniform(20, 900, PIXELS).round(),
                               generator.uniform(0, 30, PIXELS), detected,
                               1.7e9 + 0.01 * index)
            append_depth(f, index, [frame], pixels, [index != 5])
    return path


def _expected(path):
    # Each detected pixel of each complete frame: its place by the pinhole law. The column's
    # pixel p (address 8 + p) is at row 8 + p; the centre is the middle row, 15.5. Its ray
    # leaves the optical axis by atan(offset * pitch / focal) in the y-z plane.
    with h5py.File(path, "r") as f:
        group = f["depth"]
        complete = group["complete"][()]
        depth = group["depth_m"][()]
        detected = group["detected"][()]
        rows = []
        for index in range(len(complete)):
            if not complete[index]:
                continue
            for p in range(PIXELS):
                if not detected[index, p]:
                    continue
                angle = math.atan((8 + p - 15.5) * 30e-6 / 2.5e-3)
                r = depth[index, p]
                rows.append((0.0, r * math.sin(angle), r * math.cos(angle), r,
                             group["height"][index, p], group["background"][index, p],
                             group["frame"][index], 8 + p, group["time_s"][index]))
    return np.array(rows)


NAMES = ("x", "y", "z", "range", "height", "background", "frame", "pixel", "time")


def _compare(read, expected, position_tolerance=1e-6):
    assert len(read["x"]) == len(expected) > 50
    for column, name in enumerate(NAMES):
        tolerance = position_tolerance if name in ("x", "y", "z", "range") else 0
        if name in ("height", "background"):
            tolerance = 1e-4
        np.testing.assert_allclose(np.asarray(read[name], dtype=float), expected[:, column],
                                   rtol=1e-6 if name != "time" else 1e-15,
                                   atol=tolerance, err_msg=name)


def test_ply_read_by_plyfile(capture, tmp_path):
    plyfile = pytest.importorskip("plyfile")
    result = export_points(capture, tmp_path / "a.ply", "ply", GEOMETRY, comments=["depth"])
    vertex = plyfile.PlyData.read(str(tmp_path / "a.ply"))["vertex"]
    expected = _expected(capture)
    _compare({name: vertex[name] for name in NAMES}, expected)
    assert (result.points, result.frames, result.incomplete) == (len(expected), FRAMES - 1, 1)


def test_points_placed_a_block_at_a_time(capture, tmp_path, monkeypatch):
    # Blocks of 7 points, runs of 3 frames (some 30 points): blocks that end inside a run, and
    # runs that end inside a block
    plyfile = pytest.importorskip("plyfile")
    monkeypatch.setattr(points_module, "_BLOCK", 7)
    export_points(capture, tmp_path / "a.ply", "ply", GEOMETRY, run_frames=3)
    vertex = plyfile.PlyData.read(str(tmp_path / "a.ply"))["vertex"]
    _compare({name: vertex[name] for name in NAMES}, _expected(capture))


def test_pcd_read_by_pypcd4(capture, tmp_path):
    pypcd4 = pytest.importorskip("pypcd4")
    export_points(capture, tmp_path / "a.pcd", "pcd", GEOMETRY, run_frames=3)
    cloud = pypcd4.PointCloud.from_path(tmp_path / "a.pcd")
    array = cloud.numpy(NAMES)
    _compare({name: array[:, k] for k, name in enumerate(NAMES)}, _expected(capture))


def _las_points(path):
    # The LAS 1.4 header and point format 6 records, by the specification (ASPRS R15): the
    # header's offset to the points, its record length and count, its scales and offsets;
    # each record's X, Y, Z (int32), intensity, point source id and GPS time; the extra bytes
    # after the 30 bytes of format 6, in the order of the extra bytes record (float32 range,
    # height, background; uint32 frame).
    data = path.read_bytes()
    assert data[:4] == b"LASF" and data[24:26] == bytes([1, 4])
    offset, = struct.unpack_from("<I", data, 96)
    point_format, length = struct.unpack_from("<BH", data, 104)
    count, = struct.unpack_from("<Q", data, 247)
    scale = struct.unpack_from("<3d", data, 131)
    origin = struct.unpack_from("<3d", data, 155)
    assert point_format & 0x3F == 6 and length == 30 + 16
    columns = {name: [] for name in NAMES}
    for k in range(count):
        at = offset + k * length
        x, y, z, intensity = struct.unpack_from("<iiiH", data, at)
        source, time = struct.unpack_from("<Hd", data, at + 20)
        extra = struct.unpack_from("<fffI", data, at + 30)
        values = (x * scale[0] + origin[0], y * scale[1] + origin[1], z * scale[2] + origin[2],
                  *extra[:3], extra[3], source, time)
        for name, value in zip(NAMES, values):
            columns[name].append(value)
        assert intensity == min(65535, round(extra[1]))
    return columns


def test_las_read_by_the_specification_and_laspy(capture, tmp_path):
    laspy = pytest.importorskip("laspy")
    export_points(capture, tmp_path / "a.las", "las", GEOMETRY, run_frames=4)
    expected = _expected(capture)
    # 0.1 mm steps: half a step of rounding
    _compare(_las_points(tmp_path / "a.las"), expected, position_tolerance=0.5e-4 + 1e-9)
    las = laspy.read(tmp_path / "a.las")
    np.testing.assert_allclose(las.z, expected[:, 2], atol=0.5e-4 + 1e-9)
    np.testing.assert_array_equal(np.asarray(las["frame"]), expected[:, 6])


def test_mcap_read_with_its_schema(capture, tmp_path):
    pytest.importorskip("mcap_protobuf")
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory

    export_points(capture, tmp_path / "a.mcap", "mcap", GEOMETRY, run_frames=4)
    expected = _expected(capture)
    with open(tmp_path / "a.mcap", "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        messages = list(reader.iter_decoded_messages(topics=["/fliss/points"]))
    # One message per complete frame, in time order, each at its frame's time
    frames = sorted(set(expected[:, 6]))
    assert len(messages) == FRAMES - 1 >= len(frames)
    assert [m.schema.name for m in messages] == ["foxglove.PointCloud"] * len(messages)
    columns = {name: [] for name in NAMES}
    for _schema, _channel, message, decoded in messages:
        fields = {field.name: field for field in decoded.fields}
        stride = decoded.point_stride
        assert decoded.frame_id == "fliss_optical"
        for k in range(len(decoded.data) // stride):
            record = decoded.data[k * stride:(k + 1) * stride]
            for name in NAMES:
                kind = {7: "<f", 8: "<d", 5: "<I", 3: "<H"}[fields[name].type]
                columns[name].append(struct.unpack_from(kind, record, fields[name].offset)[0])
        if len(decoded.data):
            assert message.log_time == round(columns["time"][-1] * 1e9)
    _compare(columns, expected)


def _ros2_columns(clouds):
    # The points of (stamp in nanoseconds, cloud) pairs, a cloud as a PointCloud2 decoded
    # (rosbags' or mcap_ros2's object): each field where the message's fields say it is
    columns = {name: [] for name in NAMES}
    for stamp, cloud in clouds:
        assert (cloud.height, cloud.is_bigendian, cloud.is_dense) == (1, False, True)
        assert cloud.header.frame_id == "fliss_optical"
        fields = {field.name: field for field in cloud.fields}
        assert set(fields) == set(NAMES) - {"time"}
        assert all(field.count == 1 for field in fields.values())
        data = bytes(cloud.data)
        assert len(data) == cloud.width * cloud.point_step == cloud.row_step
        for k in range(cloud.width):
            for name, field in fields.items():
                kind = {7: "<f", 6: "<I"}[field.datatype]
                columns[name].append(struct.unpack_from(kind, data,
                                                        k * cloud.point_step + field.offset)[0])
            columns["time"].append(stamp / 1e9)
    return columns


def test_mcap_ros2_read_by_rosbags_and_by_its_schema(capture, tmp_path):
    pytest.importorskip("rosbags")
    pytest.importorskip("mcap_ros2")
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    from rosbags.typesys import Stores, get_typestore

    export_points(capture, tmp_path / "a.mcap", "mcap-ros2", GEOMETRY, run_frames=4)
    expected = _expected(capture)
    with open(tmp_path / "a.mcap", "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        assert reader.get_header().profile == "ros2"
        messages = list(reader.iter_decoded_messages(topics=["/fliss/points"]))
    assert len(messages) == FRAMES - 1
    for schema, channel, _message, _decoded in messages:
        assert (schema.name, schema.encoding) == ("sensor_msgs/msg/PointCloud2", "ros2msg")
        assert channel.message_encoding == "cdr"
    # rosbags: its own definition of PointCloud2 (ROS 2 Humble's), not the file's schema
    typestore = get_typestore(Stores.ROS2_HUMBLE)
    clouds = [typestore.deserialize_cdr(message.data, "sensor_msgs/msg/PointCloud2")
              for _schema, _channel, message, _decoded in messages]
    for cloud, (_schema, _channel, message, _decoded) in zip(clouds, messages):
        stamp = cloud.header.stamp.sec * 10**9 + cloud.header.stamp.nanosec
        assert stamp == message.log_time
    columns = _ros2_columns([(message.log_time, cloud) for (_schema, _channel, message, _d),
                             cloud in zip(messages, clouds)])
    # (each point's time: its message's stamp, the frame's time to the nanosecond)
    _compare(columns, expected)
    # mcap_ros2: the schema the file carries, parsed, decodes the same points
    _compare(_ros2_columns([(m.log_time, decoded) for _s, _c, m, decoded in messages]),
             expected)


def test_a_file_that_is_not_a_depth_capture_is_refused(tmp_path):
    path = tmp_path / "histograms.h5"
    with h5py.File(path, "w") as f:
        f.attrs["mode"] = "histogram"
    with pytest.raises(ValueError, match="not a depth capture"):
        export_points(path, tmp_path / "a.ply", "ply", GEOMETRY)


def test_every_writer_is_tested():
    assert set(WRITERS) == {"ply", "pcd", "las", "mcap", "mcap-ros2"}
