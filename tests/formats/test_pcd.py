from __future__ import annotations

import logging
import struct
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from dronetrack.errors import DecodeError, InputError, RecordingError
from dronetrack.formats.lzf import lzf_compress_literal, lzf_decompress
from dronetrack.formats.pcd import decode_pcd, encode_pcd, parse_pcd_header, read_pcd, write_pcd
from dronetrack.geometry.transforms import make_pose
from dronetrack.sources.recordings.pcd import PcdRecording, cloud_frame, folder_times
from dronetrack.sources.recordings.recording import ReplayOptions

XYZI = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("intensity", "<f4")])


def _cloud(n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    out = np.zeros(n, XYZI)
    for name in ("x", "y", "z"):
        out[name] = rng.uniform(-50.0, 50.0, n)
    out["intensity"] = rng.integers(0, 255, n)
    return out


# ---------------------------------------------------------------------------------------
# LZF


def _reference_lzf(data: bytes) -> bytes:
    """A slow greedy LZF compressor (longest match in the 8 KiB window) for tests."""
    out, literal, i = bytearray(), bytearray(), 0

    def flush() -> None:
        while literal:
            chunk = literal[:32]
            out.append(len(chunk) - 1)
            out.extend(chunk)
            del literal[:32]

    while i < len(data):
        best, distance = 0, 0
        for j in range(max(0, i - 8192), i):
            k = 0
            while i + k < len(data) and k < 264 and data[j + k] == data[i + k]:
                k += 1
            if k > best:
                best, distance = k, i - j - 1
        if best >= 3:
            flush()
            length = best - 2
            if length < 7:
                out.append((length << 5) | (distance >> 8))
            else:
                out.extend([(7 << 5) | (distance >> 8), length - 7])
            out.append(distance & 0xFF)
            i += best
        else:
            literal.append(data[i])
            i += 1
    flush()
    return bytes(out)


@pytest.mark.parametrize(
    ("stream", "expected"),
    [
        (b"", b""),
        (b"\x02abc", b"abc"),
        (b"\x01ab\x80\x01", b"abababab"),  # a back reference overlapping its own output
        (b"\x00a\xe0\x0a\x00", b"a" * 20),  # a long reference: length 7 + 10 + 2
        (b"\x02xyz\x20\x02\x00-", b"xyzxyz-"),  # a short reference, then a literal
        (b"\x1f" + bytes(range(32)), bytes(range(32))),  # the longest literal run
    ],
)
def test_lzf_known_answers(stream: bytes, expected: bytes) -> None:
    assert lzf_decompress(stream, len(expected)).tobytes() == expected


@pytest.mark.parametrize(
    ("stream", "size", "message"),
    [
        (b"\x05ab", 6, "ends inside"),  # a literal run longer than the rest
        (b"\x00a\x20", 4, "ends inside"),  # a reference without its offset byte
        (b"\x00a\xe0", 20, "ends inside"),  # a long reference without its length byte
        (b"\x20\x05", 3, "before the start"),
        (b"\x02abc", 2, "beyond"),
        (b"\x01ab\x80\x01", 5, "beyond"),
        (b"\x02abc", 4, "expands to 3 bytes"),
    ],
)
def test_lzf_rejects_malformed_streams(stream: bytes, size: int, message: str) -> None:
    with pytest.raises(DecodeError, match=message):
        lzf_decompress(stream, size)


@given(st.lists(st.sampled_from(b"ab\x00"), max_size=400).map(bytes))
@settings(max_examples=60)
def test_lzf_expands_what_a_reference_compressor_made(data: bytes) -> None:
    stream = _reference_lzf(data)
    assert lzf_decompress(stream, len(data)).tobytes() == data
    assert lzf_decompress(lzf_compress_literal(data), len(data)).tobytes() == data


def test_reference_compressor_compresses() -> None:
    data = b"drone " * 100
    assert len(_reference_lzf(data)) < len(data) // 10


# ---------------------------------------------------------------------------------------
# Round trips

_TYPES = ["i1", "<i2", "<i4", "<i8", "u1", "<u2", "<u4", "<u8", "<f4", "<f8"]


@st.composite
def structured(draw: st.DrawFn, allow_nan: bool = True) -> np.ndarray:
    n_fields = draw(st.integers(1, 5))
    items = []
    for k in range(n_fields):
        kind = draw(st.sampled_from(_TYPES))
        count = draw(st.integers(1, 3))
        items.append((f"f{k}", kind) if count == 1 else (f"f{k}", kind, (count,)))
    dtype = np.dtype(items)
    n = draw(st.integers(0, 12))
    return draw(arrays(dtype, n, elements={"allow_nan": allow_nan} if not allow_nan else None))


def _assert_same(a: np.ndarray, b: np.ndarray) -> None:
    assert a.dtype.names == b.dtype.names
    assert len(a) == len(b)
    for name in a.dtype.names or ():
        assert a[name].dtype == b[name].dtype
        np.testing.assert_array_equal(a[name], b[name])


@pytest.mark.parametrize("encoding", ["binary", "binary_compressed"])
@given(arr=structured())
@settings(max_examples=30)
def test_binary_round_trips_are_exact(encoding: str, arr: np.ndarray) -> None:
    back = decode_pcd(encode_pcd(arr, encoding))
    assert back.dtype.names == arr.dtype.names
    assert back.tobytes() == arr.astype(back.dtype).tobytes()


@given(arr=structured(allow_nan=False))
@settings(max_examples=40)
def test_ascii_round_trips(arr: np.ndarray) -> None:
    _assert_same(decode_pcd(encode_pcd(arr, "ascii")), arr)


@pytest.mark.parametrize("encoding", ["ascii", "binary", "binary_compressed"])
def test_files_round_trip(tmp_path: Path, encoding: str) -> None:
    write_pcd(tmp_path / "cloud.pcd", _cloud(30), encoding)
    np.testing.assert_array_equal(read_pcd(tmp_path / "cloud.pcd"), _cloud(30))


def test_ascii_keeps_nan_and_inf(tmp_path: Path) -> None:
    arr = np.array([(np.nan, np.inf, -np.inf)], dtype=[("x", "<f4"), ("y", "<f8"), ("z", "<f4")])
    write_pcd(tmp_path / "a.pcd", arr, "ascii")
    _assert_same(read_pcd(tmp_path / "a.pcd"), arr)


def test_write_rejects_what_pcd_cannot_store(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="structured"):
        write_pcd(tmp_path / "a.pcd", np.zeros(3), "binary")  # type: ignore[arg-type]
    with pytest.raises(InputError, match="encoding"):
        write_pcd(tmp_path / "a.pcd", _cloud(2), "zip")
    with pytest.raises(InputError, match="cannot store"):
        write_pcd(tmp_path / "a.pcd", np.zeros(2, [("flag", "?")]), "binary")
    with pytest.raises(InputError, match="spaces"):
        write_pcd(tmp_path / "a.pcd", np.zeros(2, [("a b", "<f4")]), "binary")


# ---------------------------------------------------------------------------------------
# Headers and corrupt files

_HEADER = """# .PCD v0.7 - Point Cloud Data file format
VERSION .7
FIELDS x y z _ rgb
SIZE 4 4 4 1 4
TYPE F F F U U
WIDTH 2
HEIGHT 1
VIEWPOINT 1 2 3 1 0 0 0
POINTS 2
DATA ascii
"""


def test_header_defaults_comments_and_padding() -> None:
    buf = (
        _HEADER.replace("FIELDS x y z _ rgb", "FIELDS x y z _ _") + "1 2 3 0 9\n4 5 6 0 8\n"
    ).encode()
    header = parse_pcd_header(buf)
    assert header.counts == (1,) * 5  # COUNT defaults to ones
    assert header.viewpoint == (1.0, 2.0, 3.0, 1.0, 0.0, 0.0, 0.0)
    assert header.dtype.names == ("x", "y", "z", "_", "__1")
    cloud = decode_pcd(buf)
    assert cloud["x"].tolist() == [1.0, 4.0]
    assert cloud["__1"].tolist() == [9, 8]


def test_a_header_without_data_line() -> None:
    with pytest.raises(DecodeError, match="no DATA"):
        decode_pcd(_HEADER.replace("DATA ascii\n", "").encode())


def test_ascii_integers_may_be_written_as_integral_floats() -> None:
    cloud = decode_pcd((_HEADER + "1 2 3 0 9.0\n4 5 6 0 8\n").encode())
    assert cloud["rgb"].tolist() == [9, 8]


def test_crlf_header_and_lowercase_keys() -> None:
    text = _HEADER.replace("DATA ascii", "data ascii").replace("\n", "\r\n")
    cloud = decode_pcd((text + "1 2 3 0 9\r\n4 5 6 0 8\r\n").encode())
    assert cloud["z"].tolist() == [3.0, 6.0]


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (("FIELDS x y z _ rgb\n", ""), "no FIELDS"),
        (("POINTS 2", "POINTS 3"), "POINTS 3"),
        (("TYPE F F F U U", "TYPE F F F U X"), "unsupported TYPE"),
        (("SIZE 4 4 4 1 4", "SIZE 4 4 4 1 3"), "unsupported TYPE"),
        (("SIZE 4 4 4 1 4", "SIZE 4 4 4 1"), "SIZE"),
        (("WIDTH 2", "WIDTH two"), "WIDTH"),
        (("VIEWPOINT 1 2 3 1 0 0 0", "VIEWPOINT 1 2"), "VIEWPOINT"),
        (("DATA ascii", "DATA zip"), "DATA 'zip'"),
        (("VERSION .7", "COLOR red"), "unknown PCD header"),
        (("VERSION .7", "WIDTH 2"), "repeats WIDTH"),
    ],
)
def test_bad_headers_raise_decode_error(edit: tuple[str, str], message: str) -> None:
    text = _HEADER.replace(*edit) + "1 2 3 0 9\n4 5 6 0 8\n"
    with pytest.raises(DecodeError, match=message):
        decode_pcd(text.encode())


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ("1 2 3 0 9\n4 5 6 0\n", "9 values"),
        ("1 2 3 0 9\n4 5 6 0 8 7\n", "11 values"),
        ("1 2 3 0 9\n4 5 six 0 8\n", "does not parse"),
        ("1 2 3 0 9\n4 5 6 0 8.5\n", "does not parse"),
        ("1 2 3 0 9\n4 5 6 -1 8\n", "does not parse"),  # -1 in a U field
    ],
)
def test_bad_ascii_data_raise_decode_error(data: str, message: str) -> None:
    with pytest.raises(DecodeError, match=message):
        decode_pcd((_HEADER + data).encode())


def test_binary_garbage_is_a_decode_error() -> None:
    with pytest.raises(DecodeError, match="not ASCII"):
        decode_pcd(bytes(range(128, 256)) + b"\n")


@pytest.mark.parametrize("encoding", ["binary", "binary_compressed"])
def test_truncated_files_raise_decode_error(tmp_path: Path, encoding: str) -> None:
    path = tmp_path / "cloud.pcd"
    write_pcd(path, _cloud(50), encoding)
    whole = path.read_bytes()
    header_end = whole.index(b"DATA") + len(f"DATA {encoding}\n")
    for cut in (header_end, header_end + 4, len(whole) - 1):
        with pytest.raises(DecodeError, match=r"truncated|missing"):
            decode_pcd(whole[:cut])


def test_compressed_sizes_must_agree(tmp_path: Path) -> None:
    path = tmp_path / "cloud.pcd"
    write_pcd(path, _cloud(10), "binary_compressed")
    whole = path.read_bytes()
    start = whole.index(b"DATA binary_compressed\n") + len(b"DATA binary_compressed\n")
    packed, unpacked = struct.unpack_from("<II", whole, start)
    wrong = whole[:start] + struct.pack("<II", packed, unpacked + 16) + whole[start + 8 :]
    with pytest.raises(DecodeError, match="expected 10 points"):
        decode_pcd(wrong)
    huge = whole.replace(b"WIDTH 10\n", b"WIDTH 100000000\n").replace(
        b"POINTS 10\n", b"POINTS 100000000\n"
    )
    start += len(huge) - len(whole)
    huge = huge[:start] + struct.pack("<II", packed, 1_600_000_000) + huge[start + 8 :]
    with pytest.raises(DecodeError, match="implausible"):
        decode_pcd(huge)


@given(
    flips=st.lists(st.tuples(st.integers(0, 10_000), st.integers(1, 255)), max_size=4),
    cut=st.integers(0, 10_000),
)
@settings(max_examples=80)
def test_corrupt_compressed_files_decode_or_raise_decode_error(
    flips: list[tuple[int, int]], cut: int
) -> None:
    buf = bytearray(_COMPRESSED)
    start = buf.index(b"DATA binary_compressed\n") + len(b"DATA binary_compressed\n")
    for pos, value in flips:
        buf[start + pos % (len(buf) - start)] ^= value
    try:
        cloud = decode_pcd(bytes(buf[: start + cut]))
    except DecodeError:
        return
    assert len(cloud) == 20


def _compressed_fixture() -> bytes:
    arr = _cloud(20)
    raw = b"".join(np.ascontiguousarray(arr[name]).tobytes() for name in XYZI.names or ())
    stream = _reference_lzf(raw)
    head = (
        "VERSION 0.7\nFIELDS x y z intensity\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\n"
        "WIDTH 20\nHEIGHT 1\nPOINTS 20\nDATA binary_compressed\n"
    )
    return head.encode() + struct.pack("<II", len(stream), len(raw)) + stream


_COMPRESSED = _compressed_fixture()


def test_a_real_lzf_stream_decodes_field_by_field() -> None:
    np.testing.assert_array_equal(decode_pcd(_COMPRESSED), _cloud(20))


# ---------------------------------------------------------------------------------------
# Frames from clouds


def test_frame_drops_nan_points_and_maps_fields() -> None:
    arr = np.zeros(
        3, [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("reflectivity", "u1"), ("ring", "<u2")]
    )
    arr["x"] = [1.0, np.nan, 3.0]
    arr["reflectivity"] = [10, 20, 30]
    arr["ring"] = [1, 2, 300]
    frame = cloud_frame(arr, 2.0, 0.1)
    assert len(frame) == 2
    assert frame.points[:, 0].tolist() == [1.0, 3.0]
    assert frame.intensity.tolist() == [10.0, 30.0]
    assert frame.line.tolist() == [1, 255]
    assert frame.t.tolist() == [2.0, 2.0]
    np.testing.assert_array_equal(frame.poses[0], np.eye(4))


def test_signalling_nans_are_dropped_or_zeroed_without_a_warning() -> None:
    fields = ("x", "y", "z", "time", "intensity", "ring")
    arr = np.zeros(2, [(name, "<f4") for name in fields])
    snan32 = np.array([0x7FA00001], dtype="<u4").view("<f4")[0]  # exponent all ones, quiet bit 0
    for name in fields:
        arr[name][0] = snan32
    arr["x"][1], arr["ring"][1] = 4.0, 7.0
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        frame = cloud_frame(arr, 2.0, 0.1)
        poisoned = cloud_frame(arr[:1].copy(), 2.0, 0.1)
    assert frame.points.tolist() == [[4.0, 0.0, 0.0]]
    assert frame.line.tolist() == [7]
    assert len(poisoned) == 0


@pytest.mark.parametrize(
    ("field", "kind", "values", "expected"),
    [
        ("offset_time", "<u4", [0, 50_000_000], [10.0, 10.05]),
        ("t", "<u4", [1_000, 2_000], [10.000001, 10.000002]),
        ("time", "<f4", [-0.05, 0.0], [9.95, 10.0]),
        ("timestamp", "<f8", [1_700_000_010.0, 1_700_000_010.5], [10.0, 10.5]),
        ("timestamp", "<f8", [1_700_000_010e9, 1_700_000_010.25e9], [10.0, 10.25]),
    ],
)
def test_point_times(field: str, kind: str, values: list[float], expected: list[float]) -> None:
    arr = np.zeros(2, [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), (field, kind)])
    arr[field] = values
    frame = cloud_frame(arr, 10.0, 0.1, origin=1_700_000_000.0)
    np.testing.assert_allclose(frame.t, expected, atol=1e-6)


def test_absolute_point_times_without_absolute_file_times_start_at_the_stamp() -> None:
    arr = np.zeros(2, [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("timestamp", "<f8")])
    arr["timestamp"] = [1_700_000_010.0, 1_700_000_010.5]
    frame = cloud_frame(arr, 3.0, 0.1, absolute=False)
    np.testing.assert_allclose(frame.t, [3.0, 3.5])


def test_cloud_without_xyz_names_its_fields() -> None:
    with pytest.raises(DecodeError, match=r"fields: a, b"):
        cloud_frame(np.zeros(1, [("a", "<f4"), ("b", "<f4")]), 0.0, 0.1)


# ---------------------------------------------------------------------------------------
# Folders


def _folder(tmp_path: Path, names: list[str], encoding: str = "binary") -> Path:
    folder = tmp_path / "scans"
    folder.mkdir()
    for k, name in enumerate(names):
        write_pcd(folder / name, _cloud(5 + k, seed=k), encoding)
    return folder


def test_times_from_decimal_names(tmp_path: Path) -> None:
    names = ["1700000000.200000.pcd", "1700000000.000000.pcd", "1700000000.100000.pcd"]
    rec = PcdRecording(_folder(tmp_path, names), ReplayOptions())
    assert rec.origin == pytest.approx(1_700_000_000.0)
    np.testing.assert_allclose(rec.times, [0.0, 0.1, 0.2], atol=1e-9)
    assert rec.period == pytest.approx(0.1)
    frames = list(rec.frames())
    assert [f.stamp for f in frames] == pytest.approx([0.0, 0.1, 0.2])
    assert [len(f) for f in frames] == [6, 7, 5]  # file 1 (6 points) is the earliest
    assert all(f.duration == pytest.approx(0.1) for f in frames)
    assert not rec.skipped


@pytest.mark.parametrize(
    ("names", "origin", "times"),
    [
        (["1700000000000000000.pcd", "1700000000050000000.pcd"], 1.7e9, [0.0, 0.05]),
        (["cloud_1700000000000000.pcd", "cloud_1700000000050000.pcd"], 1.7e9, [0.0, 0.05]),
        (["1700000000000.pcd", "1700000000050.pcd"], 1.7e9, [0.0, 0.05]),
        (["1700000000.pcd", "1700000001.pcd"], 1.7e9, [0.0, 1.0]),
    ],
)
def test_integer_name_units(names: list[str], origin: float, times: list[float]) -> None:
    got = folder_times([Path(n) for n in names], None, 0.1)
    assert got.absolute
    assert got.origin == pytest.approx(origin)
    np.testing.assert_allclose(got.t, times, atol=1e-9)


def test_index_names_use_the_period(tmp_path: Path) -> None:
    folder = _folder(tmp_path, ["000012.pcd", "000010.pcd", "000011.pcd"])
    rec = PcdRecording(folder, ReplayOptions(period_s=0.05))
    assert [f.name for f in rec.files] == ["000010.pcd", "000011.pcd", "000012.pcd"]
    np.testing.assert_allclose(rec.times, [0.0, 0.05, 0.1])
    assert rec.origin == pytest.approx(0.5)
    assert rec.period == 0.05
    default = PcdRecording(folder, ReplayOptions())
    assert default.period == 0.1


def test_names_without_numbers_are_in_name_order(tmp_path: Path) -> None:
    got = folder_times([Path("a.pcd"), Path("b.pcd")], None, 0.2)
    assert not got.absolute
    np.testing.assert_allclose(got.t, [0.0, 0.2])
    with pytest.raises(RecordingError, match=r"c\.pcd has no number"):
        folder_times([Path("1.pcd"), Path("c.pcd")], None, 0.1)


def test_times_from_a_file_of_times(tmp_path: Path) -> None:
    folder = _folder(tmp_path, ["a.pcd", "b.pcd", "c.pcd"])
    stamps = tmp_path / "times.txt"
    stamps.write_text("# time of each file\n100.5\n100.25\n100.75\n")
    rec = PcdRecording(folder, ReplayOptions(timestamps=stamps))
    assert [f.name for f in rec.files] == ["b.pcd", "a.pcd", "c.pcd"]
    assert rec.origin == 100.25
    np.testing.assert_allclose(rec.times, [0.0, 0.25, 0.5])
    stamps.write_text("1.7e9\n1700000000.5\n1700000001\n")  # any non-integer: all seconds
    rec = PcdRecording(folder, ReplayOptions(timestamps=stamps))
    assert rec.origin == 1.7e9
    np.testing.assert_allclose(rec.times, [0.0, 0.5, 1.0])
    stamps.write_text("1\n2\n")
    with pytest.raises(RecordingError, match="2 times for 3"):
        PcdRecording(folder, ReplayOptions(timestamps=stamps))


def test_times_from_a_file_of_names(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    folder = _folder(tmp_path, ["a.pcd", "b.pcd", "c.pcd"])
    stamps = tmp_path / "times.csv"
    stamps.write_text("file,time\na.pcd,1700000000000000000\nc,1700000000100000000\n")
    with caplog.at_level(logging.WARNING):
        rec = PcdRecording(folder, ReplayOptions(timestamps=stamps))
    assert [f.name for f in rec.files] == ["a.pcd", "c.pcd"]
    np.testing.assert_allclose(rec.times, [0.0, 0.1])
    assert rec.skipped["no_timestamp"] == 1
    assert "b.pcd" in caplog.text
    stamps.write_text("a.pcd,1\n2\n")
    with pytest.raises(RecordingError, match="mixes"):
        PcdRecording(folder, ReplayOptions(timestamps=stamps))
    stamps.write_text("a.pcd,1\nb.pcd,soon\n")
    with pytest.raises(RecordingError, match="line 2"):
        PcdRecording(folder, ReplayOptions(timestamps=stamps))
    with pytest.raises(RecordingError, match="cannot read timestamps"):
        PcdRecording(folder, ReplayOptions(timestamps=tmp_path / "nope.txt"))


def test_a_corrupt_file_is_skipped_and_counted(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    folder = _folder(tmp_path, ["1.5.pcd", "1.6.pcd", "1.7.pcd", "1.8.pcd"])
    (folder / "1.6.pcd").write_bytes(b"\x00\xffnot a pcd")  # the header does not parse
    whole = (folder / "1.7.pcd").read_bytes()
    (folder / "1.7.pcd").write_bytes(whole[:-10])  # the data are cut short
    with caplog.at_level(logging.WARNING, logger="dronetrack.formats.pcd"):
        rec = PcdRecording(folder, ReplayOptions())
        frames = list(rec.frames())
    assert [f.stamp for f in frames] == pytest.approx([0.0, 0.3])
    assert rec.skipped == {"bad_pcd": 2}
    assert "1.6.pcd" in caplog.text
    assert "1.7.pcd" in caplog.text


def test_a_file_without_xyz_is_skipped(tmp_path: Path) -> None:
    folder = _folder(tmp_path, ["1.pcd"])
    write_pcd(folder / "2.pcd", np.zeros(3, [("a", "<f4")]))
    rec = PcdRecording(folder, ReplayOptions())
    assert len(list(rec.frames())) == 1
    assert rec.skipped["bad_pcd"] == 1


def test_folder_errors(tmp_path: Path) -> None:
    with pytest.raises(RecordingError, match="does not exist"):
        PcdRecording(tmp_path / "nowhere", ReplayOptions())
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / "notes.txt").write_text("hi")
    with pytest.raises(RecordingError, match=r"no \.pcd files"):
        PcdRecording(tmp_path / "empty", ReplayOptions())
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "1.pcd").write_text("VERSION 0.7\n")
    with pytest.raises(RecordingError, match=r"no readable \.pcd file.*(no FIELDS|no DATA)"):
        PcdRecording(bad, ReplayOptions())
    with pytest.raises(RecordingError, match="not a PCD file"):
        PcdRecording(tmp_path / "empty" / "notes.txt", ReplayOptions())
    with pytest.raises(InputError, match="sensor_pose"):
        PcdRecording(_folder(tmp_path, ["1.pcd"]), ReplayOptions(sensor_pose=np.eye(3)))


def test_a_single_file_with_a_sensor_pose(tmp_path: Path) -> None:
    path = tmp_path / "1700000000.5.pcd"
    write_pcd(path, _cloud(4), "ascii")
    pose = make_pose(np.eye(3), [1.0, 2.0, 3.0])
    rec = PcdRecording(path, ReplayOptions(sensor_pose=pose))
    (frame,) = rec.frames()
    assert rec.origin == 1_700_000_000.5
    assert frame.stamp == 0.0
    np.testing.assert_array_equal(frame.poses[0], pose)
    np.testing.assert_allclose(frame.points, np.column_stack([_cloud(4)[k] for k in "xyz"]))


def test_info(tmp_path: Path) -> None:
    folder = _folder(tmp_path, ["1.0.pcd", "1.1.pcd", "1.2.pcd"])
    write_pcd(folder / "1.3.pcd", _cloud(3), "ascii")
    info = PcdRecording(folder, ReplayOptions()).info()
    assert info.kind == "pcd"
    assert info.path == folder
    assert info.start == pytest.approx(1.0)
    assert info.duration_s == pytest.approx(0.3)
    assert [(t.topic, t.msgtype, t.count) for t in info.topics] == [
        ("scans", "pcd/ascii", 1),
        ("scans", "pcd/binary", 3),
    ]
