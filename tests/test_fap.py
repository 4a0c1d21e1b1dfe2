"""FAP streams and .fap files: the writer's interoperable subset, the liberal reader, real files."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from prosody.cli import main
from prosody.errors import ConfigError, FapFormatError, FapWriteError
from prosody.fap.fapfile import format_fap, read_fap, write_fap
from prosody.fap.stream import FapStream
from prosody.fap.table import FAPS, N_FAPS, fap_info

MASK_ZEROS = " ".join(["0"] * N_FAPS)

# irregular files are read with a warning each (asserted where it matters): not errors in these tests
pytestmark = pytest.mark.filterwarnings("ignore::prosody.errors.FapIrregularityWarning")



def _mask_line(*faps: int, tokens: int = N_FAPS) -> str:
    return " ".join("1" if j + 1 in faps else "0" for j in range(tokens))


# the table ------------------------------------------------------------------------------------------
def test_fap_table_numbers_names_units() -> None:
    assert [info.number for info in FAPS] == list(range(1, 69))
    assert fap_info(31).name == "raise_l_i_eyebrow" and fap_info(31).fapu == "ENS"
    assert fap_info("head_roll").number == 50 and fap_info(50).fapu == "AU"
    assert fap_info(3).name == "open_jaw" and fap_info(3).fapu == "MNS"
    with pytest.raises(KeyError, match="69"):
        fap_info(69)


# the stream -----------------------------------------------------------------------------------------
def test_stream_select_merge_and_physical_units() -> None:
    prosody = FapStream.from_curves({48: np.array([1000.0, -2000.0, 0.0]), 31: np.array([0, 512.0, 1024])},
                                    fps=30)
    lips = FapStream.from_curves({3: np.array([10.0, 20.0, 30.0, 40.0]), 48: np.full(4, 7.0)}, fps=30)
    merged = prosody.merged_over(lips)
    assert merged.active_faps == (3, 31, 48)
    np.testing.assert_array_equal(merged.curve(3), [10, 20, 30])
    np.testing.assert_array_equal(merged.curve(48), [1000, -2000, 0])  # ours wins over the base
    assert merged.select([3]).active_faps == (3,)
    assert merged.without([3]).active_faps == (31, 48)
    physical = merged.to_physical()
    np.testing.assert_allclose(physical[:, 47], [0.01, -0.02, 0.0])  # AU -> rad
    np.testing.assert_allclose(physical[:, 30], [0.0, 0.5, 1.0])  # ENS -> fraction of ENS0
    assert np.isnan(physical[0, 10])  # masked off


def test_stream_resample_and_merge_across_rates() -> None:
    base = FapStream.from_curves({3: np.arange(25.0)}, fps=25)  # 1 s
    ours = FapStream.from_curves({48: np.zeros(30)}, fps=30)
    merged = ours.merged_over(base)
    np.testing.assert_allclose(merged.curve(3)[:5], np.arange(5) * 25 / 30)


def test_stream_copies_only_what_changes() -> None:
    stream = FapStream.from_curves({48: np.array([1.0, 2.0]), 31: np.array([3.0, 4.0])}, fps=30)
    # identity operations give the same stream; a rename or dropping a FAP shares the values
    assert stream.scaled({48: 1.0}) is stream and stream.without([49]) is stream
    assert np.shares_memory(stream.renamed("other").values, stream.values)
    halved = stream.scaled({48: 0.5})
    np.testing.assert_array_equal(halved.curve(48), [0.5, 1.0])
    np.testing.assert_array_equal(stream.curve(48), [1.0, 2.0])  # the original is untouched
    dropped = stream.without([48])
    assert dropped.active_faps == (31,) and not np.any(dropped.values[:, 47])  # masked off means 0
    np.testing.assert_array_equal(stream.curve(48), [1.0, 2.0])
    # a stream owns its arrays: changing the caller's array later changes nothing
    values, mask = np.zeros((2, 68)), np.zeros((2, 68), bool)
    mask[:, 47] = True
    values[:, 47] = 5.0
    owned = FapStream(values, mask, 30)
    values[:, 47] = 9.0
    np.testing.assert_array_equal(owned.curve(48), [5.0, 5.0])
    with pytest.raises(ValueError):
        owned.values[0, 47] = 1.0  # read-only


def test_stream_refuses_bad_shapes() -> None:
    with pytest.raises(ConfigError):
        FapStream(np.zeros((3, 67)), np.zeros((3, 67), bool), 30)
    with pytest.raises(ConfigError):
        FapStream.from_curves({48: np.zeros(3), 49: np.zeros(4)}, fps=30)
    with pytest.raises(ConfigError):
        FapStream.from_curves({48: np.array([np.nan])}, fps=30)
    with pytest.raises(ConfigError):
        FapStream.from_curves({70: np.zeros(3)}, fps=30)


# the writer -----------------------------------------------------------------------------------------
def test_writer_produces_the_interoperable_subset(tmp_path) -> None:
    stream = FapStream.from_curves(
        {1: np.array([5.0, 5.0]), 2: np.array([1.0, 1.0]), 48: np.array([1.4, -2.5]), 31: np.array([2.5, 3.5])},
        fps=30, name="my clip",
    )
    text = format_fap(stream)
    assert text == (
        "2.1 my_clip 30 2\n"
        f"{_mask_line(31, 48)} \n0 2 1 \n"
        f"{_mask_line(31, 48)} \n1 4 -2 \n"
    )
    path = tmp_path / "out.fap"
    write_fap(stream, path)
    raw = path.read_bytes()
    assert raw.startswith(b"2.1 out 30 2\n") and raw.endswith(b"\n") and not raw.endswith(b"\n\n")
    assert b"\r" not in raw and b"#" not in raw


def test_writer_refuses_what_players_cannot_read(tmp_path) -> None:
    with pytest.raises(FapWriteError, match="integer"):
        format_fap(FapStream.from_curves({48: np.zeros(3)}, fps=29.97))
    with pytest.raises(FapWriteError, match="exceeds 16777216"):
        format_fap(FapStream.from_curves({48: np.array([2.0**24 + 1])}, fps=30))
    assert format_fap(FapStream.from_curves({48: np.array([2.0**24])}, fps=30)).endswith(f" {2**24} \n")
    with pytest.raises(FapWriteError, match="no frame"):
        format_fap(FapStream.empty(0, fps=30))
    path = tmp_path / "x.fap"
    with pytest.raises(FapWriteError):
        write_fap(FapStream.from_curves({48: np.zeros(3)}, fps=29.97), path)
    assert not path.exists() and not list(tmp_path.iterdir())


def test_empty_frames_write_a_bare_frame_number() -> None:
    assert format_fap(FapStream.empty(1, fps=25, name="e")) == f"2.1 e 25 1\n{MASK_ZEROS} \n0 \n"


def _atoi(token: str) -> int:
    """C's atoi: leading whitespace skipped, then a sign and digits, the rest ignored."""
    import re

    match = re.match(r"\s*([+-]?\d+)", token)
    return int(match[1]) if match else 0


def test_greta_buffer_reading_from_space_to_space_reads_every_token(rng) -> None:
    # C++ Greta's FAPdata::ReadFapBuffer takes the text between two spaces as one number (atoi): a line that
    # ends without a space glues its last number to the next line's first, and the next line's first is lost
    values = {fap: rng.normal(0, 300, 5) for fap in (3, 31, 48, 49, 50, 59)}
    text = format_fap(FapStream.from_curves(values, fps=25))
    body = text.split("\n", 1)[1]  # the header line is read by line
    tokens = body.split()
    assert [_atoi(piece) for piece in body.split(" ") if piece.strip()] == [int(t) for t in tokens]
    assert all(line.endswith(" ") for line in body.splitlines())


@settings(max_examples=60, deadline=None)
@given(
    st.integers(min_value=1, max_value=12),
    st.integers(min_value=1, max_value=60),
    st.randoms(use_true_random=False),
)
def test_round_trip_random_masks_and_values(n_frames: int, fps: int, random) -> None:
    seed = random.randint(0, 2**32 - 1)
    generator = np.random.default_rng(seed)
    values = generator.integers(-50000, 50000, size=(n_frames, N_FAPS)).astype(float)
    mask = generator.random((n_frames, N_FAPS)) < 0.3
    mask[:, :2] = False
    stream = FapStream(values, mask, float(fps), "rt")
    text = format_fap(stream)
    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory() as directory:
        path = Path(directory) / "rt.fap"
        path.write_text(text)
        back = read_fap(path)
    assert back.warnings == () and back.version == "2.1" and back.header_frames == n_frames
    np.testing.assert_array_equal(back.stream.mask, mask)
    np.testing.assert_array_equal(back.stream.values, np.where(mask, values, 0))
    assert back.stream.fps == fps


# the reader on hand-made irregular files -------------------------------------------------------------
def _write(tmp_path, text: str, name: str = "f.fap", newline: str = "\n"):
    path = tmp_path / name
    path.write_bytes(text.replace("\n", newline).encode("latin-1"))
    return path


def test_reader_is_liberal(tmp_path) -> None:
    text = (
        "# made by hand\n"
        "2.0 C:\\some path\\my name 25 3\n"
        "# between\n"
        f"{_mask_line(48, 49)} \n"
        "1\t100\t-5.5  \n"
        "\n"
        f"{_mask_line(48, 49, 50, tokens=69)}\n"
        "2 101 -6 7\n"
    )
    fap = read_fap(_write(tmp_path, text, newline="\r\n"))
    assert fap.version == "2.0" and fap.stream.name == "C:\\some path\\my name" and fap.stream.fps == 25
    assert fap.header_frames == 3 and fap.stream.n_frames == 2 and fap.first_frame_number == 1
    assert not fap.integer_values
    np.testing.assert_array_equal(fap.stream.curve(48), [100, 101])
    np.testing.assert_array_equal(fap.stream.curve(49), [-5.5, -6])
    np.testing.assert_array_equal(fap.stream.mask[:, 49], [False, True])
    joined = " | ".join(fap.warnings)
    for expected in ("comment", "69 tokens", "start at 1", "promises 3 frames", "non-integer"):
        assert expected in joined


@pytest.mark.parametrize(
    ("text", "line", "expected"),
    [
        ("2.1 x 25\n", 1, "the frame rate"),  # three tokens: the name stands where the rate should
        ("2.1 x 25 abc\n", 1, "the number of frames"),
        ("2.1 x 25 1\n0 1 0\n0 5\n", 2, "mask line of 68"),
        (f"2.1 x 25 1\n{_mask_line(48)}\n0\n", 3, "1 values"),
        (f"2.1 x 25 1\n{_mask_line(48)}\n0 1 2\n", 3, "1 values"),
        (f"2.1 x 25 1\n{_mask_line(48)}\n0 abc\n", 3, "a FAP value"),
        (f"2.1 x 25 1\n{_mask_line(48)}\n", 2, "without a value line"),
        (f"2.1 x 25 1\n{_mask_line(48)}\n0.5 3\n", 3, "not an integer"),
        ("# only comments\n\n", None, "no header"),
        ("hello world\n", 1, "expected a header"),
    ],
)
def test_reader_errors_name_file_line_and_expectation(tmp_path, text, line, expected) -> None:
    path = _write(tmp_path, text)
    with pytest.raises(FapFormatError) as caught:
        read_fap(path)
    message = str(caught.value)
    assert str(path) in message and expected in message
    if line is not None:
        assert f"line {line}:" in message
    assert caught.value.line == line


def test_reader_missing_file(tmp_path) -> None:
    with pytest.raises(FapFormatError, match="no such file"):
        read_fap(tmp_path / "nope.fap")


# the real corpus ------------------------------------------------------------------------------------
REAL = {
    # file: (version, fps, frames, header frames, {(frame, fap): value read by hand in the file})
    "xface-new/anger.fap": ("2.1", 25, 108, 108, {(0, 3): 0, (0, 4): 10, (0, 5): 10, (0, 6): 0, (0, 8): 10}),
    "xface-new/joy.fap": ("2.1", 25, 108, 108, {(0, 4): 10, (0, 8): 10}),
    "xface-new/fear.fap": ("2.1", 25, 107, 107, {(0, 4): 10}),
    "SEMAINE-3.1/bari21_1.fap": ("2.1", 25, 408, 408, {(407, 3): 9, (407, 4): -7, (407, 5): -29, (407, 6): 14,
                                                       (407, 13): 0}),
    "SEMAINE-3.1/empty.fap": ("2.1", 25, 1, 1, {}),
    "SEMAINE-3.1/example2_headerless_stream.fap": (None, 25, 50, None, {(0, 3): 0}),
    "greta/1-Welcome_1.fap": ("2.1", 25, 1, 1, {(0, 1): 0}),
    "greta/AU Interpolation_1111.fap": ("2.1", 25, 1, 1, {(0, 19): 0, (0, 22): 0}),
    "greta/UniqueId_214.fap": ("2.1", 25, 1, 1, {(0, 1): 0}),
    "vreng/joy.fap": ("2.1", 10, 20, 20, {(1, 55): -19, (1, 57): -19, (1, 58): -19, (1, 56): 0}),
    "vreng/anger.fap": ("2.1", 10, 23, 23, {(1, 31): 0, (1, 32): -18, (1, 38): 9}),
    "vreng/jag.fap": ("2.0", 5, 169, 169, {(0, 3): 57, (0, 4): 26, (0, 5): -114, (1, 3): 58, (1, 4): 28,
                                          (1, 5): -116}),
}


@pytest.mark.shared_data
@pytest.mark.parametrize("relative", sorted(REAL))
def test_real_fap_files(shared_data, relative: str, tmp_path) -> None:
    version, fps, frames, header_frames, known = REAL[relative]
    fap = read_fap(shared_data / "fap-files" / relative)
    assert fap.version == version
    assert fap.stream.fps == fps and fap.stream.n_frames == frames and fap.header_frames == header_frames
    for (frame, number), value in known.items():
        assert fap.stream.mask[frame, number - 1], (frame, number)
        assert fap.stream.values[frame, number - 1] == value, (frame, number)
    # what we write from it reads back to the same integers (FAP 1 and 2 are dropped by design)
    out = tmp_path / "copy.fap"
    write_fap(fap.stream, out)
    back = read_fap(out)
    kept = fap.stream.mask.copy()
    kept[:, :2] = False
    np.testing.assert_array_equal(back.stream.mask, kept)
    np.testing.assert_array_equal(back.stream.values[kept], np.rint(fap.stream.values[kept]))


@pytest.mark.shared_data
def test_real_files_warnings(shared_data) -> None:
    greta = read_fap(shared_data / "fap-files" / "greta" / "AU Interpolation_1111.fap")
    assert greta.stream.name == "AU Interpolation_1111.fap"
    assert any("69 tokens" in warning for warning in greta.warnings)
    headerless = read_fap(shared_data / "fap-files" / "SEMAINE-3.1" / "example2_headerless_stream.fap")
    assert any("headerless" in warning for warning in headerless.warnings)
    bari = read_fap(shared_data / "fap-files" / "SEMAINE-3.1" / "bari21_1.fap")
    counts = bari.stream.mask.sum(axis=1)
    # per-frame masks change: SOURCES.txt counts 41..51 tokens per value line, frame number included
    assert counts.min() == 40 and counts.max() == 50


# inspect ----------------------------------------------------------------------------------------------
def test_inspect_json_exact_shape(tmp_path, capsys) -> None:
    text = f"2.1 demo 25 2\n{_mask_line(31, 48)}\n0 5 -100\n{_mask_line(48)}\n1 200\n"
    path = _write(tmp_path, text)
    assert main(["inspect", str(path), "--json"]) == 0
    payload = json.loads(capsys.readouterr().out)
    assert payload == {"version": "2.1", "name": "demo", "fps": 25, "frames": 2,
                       "faps": {"31": [5, None], "48": [-100, 200]}}


def test_inspect_summary_names_faps_and_physical_ranges(tmp_path, capsys) -> None:
    path = _write(tmp_path, f"2.1 demo 25 2\n{_mask_line(48)}\n0 100000\n{_mask_line(48)}\n1 -50000\n")
    assert main(["inspect", str(path)]) == 0
    out = capsys.readouterr().out
    assert "head_pitch" in out and "0.08 s" in out
    assert f"{np.degrees(1.0):+10.4g}" in out and f"{np.degrees(-0.5):+10.4g}" in out


def test_inspect_malformed_file_exit_1(tmp_path, capsys) -> None:
    path = _write(tmp_path, "2.1 x 25 1\n0 1 0\n0 5\n")
    assert main(["inspect", str(path)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "line 2" in err


def _token_stream_reader(text: str) -> tuple[int, list[dict[int, float]]]:
    """Read a .fap file the way Xface's FAPFile::open does: whitespace tokens, not lines.

    Header: version, ONE name token, fps, frame count; then per frame 68 mask integers, the frame number
    used as an index into a table of ``count`` frames, and one token per set bit (FAP 1 and 2 would need
    4 and 6 tokens, so a writer must leave them off).
    """
    tokens = text.split()
    _version, _name, fps, count = tokens[:4]
    frames: list[dict[int, float]] = [{} for _ in range(int(count))]
    position = 4
    while position < len(tokens):
        mask = [int(token) for token in tokens[position : position + 68]]
        position += 68
        row = int(tokens[position])
        position += 1
        assert 0 <= row < int(count), "frame index outside the header's table"
        for j, bit in enumerate(mask):
            if bit:
                assert j >= 2, "FAP 1/2 would consume several tokens"
                frames[row][j + 1] = float(tokens[position])
                position += 1
    return int(float(fps)), frames


def test_written_files_parse_in_a_token_stream_reader(tmp_path, rng) -> None:
    curves = {fap: rng.normal(0, 3000, size=40) for fap in (31, 32, 33, 34, 48, 49, 50)}
    stream = FapStream.from_curves({1: np.ones(40), **curves}, fps=30, name="name with spaces")
    path = tmp_path / "spaces in path.fap"
    write_fap(stream, path)
    fps, frames = _token_stream_reader(path.read_text())
    assert fps == 30 and len(frames) == 40
    for k, frame in enumerate(frames):
        assert frame == {fap: float(np.rint(curve[k])) for fap, curve in curves.items()}


# hostile and unusual .fap input --------------------------------------------------------------------------
def test_full_form_viseme_and_expression_values_are_read(tmp_path) -> None:
    # FAP 1 with its 4 values (select1 select2 blend def) and FAP 2 with its 6, as Xface and the C++ Greta read
    text = "2.1 v 25 2\n" + _mask_line(1, 2, 3) + "\n0 7 0 0 0 4 3 0 0 0 0 120\n" + _mask_line(3) + "\n1 130\n"
    fap = read_fap(_write(tmp_path, text))
    assert fap.stream.curve(1).tolist() == [7.0, 0.0] and fap.stream.curve(2).tolist() == [4.0, 0.0]
    assert fap.stream.curve(3).tolist() == [120.0, 130.0]
    assert any("multi-value form" in warning for warning in fap.warnings)


@pytest.mark.parametrize("text, match", [
    ("2.1 x 0.0001 1\n" + _mask_line(48) + "\n0 10\n", "outside 1-1000 fps"),
    ("2.1 x 1e9 1\n" + _mask_line(48) + "\n0 10\n", "outside 1-1000 fps"),
    ("2.1 x 30 1\n" + _mask_line(48) + "\n0 1e400\n", "out of range"),
    ("2.1 x 30 1e400\n" + _mask_line(48) + "\n0 1\n", "out of range"),
    ("2.1 x 30 1\n" + "1" * 100_000 + "\n", "longer than 65536 bytes"),
    ("RIFF\0\0\0\0WAVEfmt \n", "binary data"),
])
def test_hostile_files_cost_nothing_and_say_why(tmp_path, text, match) -> None:
    with pytest.raises(FapFormatError, match=match):
        read_fap(_write(tmp_path, text))


def test_an_endless_device_is_refused(tmp_path) -> None:
    with pytest.raises(FapFormatError, match="a device, not a regular file"):
        read_fap("/dev/zero")


def test_ground_truth_and_base_at_another_length_are_refused_before_resampling(tmp_path) -> None:
    from prosody.errors import GroundTruthError
    from prosody.fap.recorded import fit_to_grid

    slow = FapStream.from_curves({48: np.zeros(3)}, fps=1.0)  # 3 s at 1 fps
    with pytest.raises(GroundTruthError, match="lasts 3.00 s"):
        fit_to_grid(slow, n_frames=30_000, fps=30.0, source="slow.fap")  # 1000 s of audio
    assert fit_to_grid(slow, n_frames=90, fps=30.0, source="ok.fap").n_frames == 90


def test_header_names_are_ascii_and_short_enough_for_every_player(tmp_path) -> None:
    from prosody.fap.fapfile import FapNameWarning

    stream = FapStream.from_curves({48: np.zeros(2)}, fps=30)
    with pytest.warns(FapNameWarning, match="written as"):
        text = format_fap(stream, name="é" * 3 + "x" * 300)
    header = text.splitlines()[0]
    assert header == "2.1 " + "___" + "x" * 97 + " 30 2" and header.isascii()


def test_irregularities_are_a_warning_category_and_strict_refuses_them(tmp_path, capsys) -> None:
    from prosody.errors import FapIrregularityWarning

    path = _write(tmp_path, "# made by hand\n2.1 x 30 1\n" + _mask_line(48) + "\n1 10\n")
    with pytest.warns(FapIrregularityWarning) as caught:
        fap = read_fap(path)
    messages = [str(w.message) for w in caught]
    assert any("comment lines" in m for m in messages) and any("start at 1" in m for m in messages)
    assert all(m.startswith(str(path)) for m in messages) and len(messages) == len(fap.warnings)
    with pytest.raises(FapFormatError, match="strict reading"):
        read_fap(path, strict=True)
    assert main(["inspect", str(path), "--strict"]) == 1
    strict_err = capsys.readouterr().err
    assert "irregular .fap file (strict reading)" in strict_err and strict_err.count("\n") == 1
    assert main(["inspect", str(path)]) == 0
    err = capsys.readouterr().err
    assert err.count("comment lines") == 1 and err.count("warning:") == 2  # each irregularity said once


def test_inspect_and_reports_speak_degrees_and_fap_units(tmp_path) -> None:
    from prosody.fap.inspect import inspect_summary

    stream = FapStream.from_curves({31: np.array([0.0, 24.0]), 48: np.array([0.0, 17453.3]),
                                    3: np.array([0.0, 300.0])}, fps=30)
    write_fap(stream, tmp_path / "x.fap")
    summary = inspect_summary(read_fap(tmp_path / "x.fap"))
    words = " ".join(summary.split())
    assert "+24 ENS" in words and "+10 deg" in words  # 17453 AU = 0.1745 rad = 10 degrees
    assert "+300 MNS" in words and "ENS0" not in summary
