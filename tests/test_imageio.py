"""engine.imageio: EXR round trips (bit-exact float32), custom channels, header, row order."""
import numpy as np
import pytest

from ember.engine import imageio


def _random(shape, seed=0):
    rng = np.random.default_rng(seed)
    # Wide dynamic range, including values float16 could not hold and exact zeros.
    a = (rng.standard_normal(shape) * 10.0 ** rng.integers(-6, 7, shape)).astype(np.float32)
    a.flat[0] = 0.0
    return a


def test_round_trip_bit_exact_float32(tmp_path):
    img = _random((7, 11, 4))
    p = tmp_path / "rgba.exr"
    imageio.write_rgba_exr(p, img)
    channels, _ = imageio.read_exr(p)
    assert sorted(channels) == ["A", "B", "G", "R"]
    for i, c in enumerate("RGBA"):
        assert channels[c].dtype == np.float32
        assert channels[c].shape == (7, 11)
        # bit-exact, including the sign of zero and tiny values
        assert np.array_equal(channels[c].view(np.uint32), img[:, :, i].view(np.uint32))
    rgb = imageio.read_rgb(p)
    assert rgb.shape == (7, 11, 3) and rgb.dtype == np.float32
    assert np.array_equal(rgb, img[:, :, :3])


def test_custom_channels_and_header(tmp_path):
    names = ["R", "G", "B", "A", "var.R", "var.G", "var.B"]
    chans = {n: _random((5, 6), seed=i) for i, n in enumerate(names)}
    header = {"renderer": "Cycles 5.0.1", "samples": 1024, "runs": 16, "time_s": 12.5,
              "settings": {"max_bounces": 64, "denoise": False}, "flag": True}
    p = tmp_path / "custom.exr"
    imageio.write_exr(p, chans, header)
    got, hdr = imageio.read_exr(p)
    assert set(got) == set(names)
    for n in names:
        assert np.array_equal(got[n], chans[n])
    assert hdr["renderer"] == "Cycles 5.0.1"
    assert hdr["samples"] == 1024 and hdr["runs"] == 16
    assert hdr["time_s"] == pytest.approx(12.5)
    assert hdr["flag"] == 1
    import json
    assert json.loads(hdr["settings"]) == {"max_bounces": 64, "denoise": False}


def test_rows_are_top_down(tmp_path):
    # A gradient whose row 0 is the brightest must come back with row 0 first, and the
    # EXR data window must start at the top-left (0, 0) with increasing-y line order.
    h, w = 4, 3
    img = np.repeat(np.arange(h, 0, -1, dtype=np.float32)[:, None], w, axis=1)
    p = tmp_path / "rows.exr"
    imageio.write_exr(p, {"Y": img})
    got, hdr = imageio.read_exr(p)
    assert np.array_equal(got["Y"], img)
    lo, hi = hdr["dataWindow"]
    assert tuple(lo) == (0, 0) and tuple(hi) == (w - 1, h - 1)
    assert "INCREASING_Y" in str(hdr["lineOrder"])


def test_half_channels(tmp_path):
    a = np.linspace(0, 2, 12, dtype=np.float32).reshape(3, 4)
    p = tmp_path / "half.exr"
    imageio.write_exr(p, {"R": a, "var.R": a}, half=["var.R"])
    got, _ = imageio.read_exr(p)
    assert got["R"].dtype == np.float32 and np.array_equal(got["R"], a)
    assert got["var.R"].dtype == np.float16
    assert np.array_equal(got["var.R"], a.astype(np.float16))


def test_rejects_bad_input(tmp_path):
    p = tmp_path / "bad.exr"
    with pytest.raises(ValueError):
        imageio.write_exr(p, {"R": np.zeros((2, 2)), "G": np.zeros((2, 3))})
    with pytest.raises(ValueError):
        imageio.write_exr(p, {"R": np.zeros((2, 2, 2))})
    with pytest.raises(ValueError):
        imageio.write_exr(p, {"R": np.zeros((2, 2))}, {"compression": "none"})
    with pytest.raises(ValueError):
        imageio.write_exr(p, {"R": np.zeros((2, 2))}, half=["G"])
    with pytest.raises(KeyError):
        imageio.write_exr(p, {"Y": np.zeros((2, 2))})
        imageio.read_rgb(p)


def test_large_int_header_kept_as_string(tmp_path):
    p = tmp_path / "int.exr"
    imageio.write_exr(p, {"R": np.zeros((1, 1))}, {"big": 2 ** 40, "np": np.int64(7)})
    _, hdr = imageio.read_exr(p)
    assert hdr["big"] == str(2 ** 40) and hdr["np"] == 7


@pytest.mark.parametrize("name", ["cornell_box_cycles.exr", "lights_cycles.exr"])
def test_cycles_reference_files(name):
    """The committed Cycles references (scenes/reference.py) have the promised layout."""
    import json
    import pathlib
    path = pathlib.Path(__file__).parent / "data" / name
    if not path.exists():
        pytest.skip(f"{name} not generated")
    ch, hdr = imageio.read_exr(path)
    assert set(ch) == {"R", "G", "B", "var.R", "var.G", "var.B"}
    for c in ch.values():
        assert c.dtype == np.float32 and c.shape == (64, 64)
        assert np.all(np.isfinite(c)) and np.all(c >= 0)
    assert hdr["runs"] >= 2 and hdr["samples"] >= 1 and hdr["resolution"] == "64x64"
    assert hdr["rows"] == "top-down" and hdr["blender_version"].startswith("5.")
    settings = json.loads(hdr["settings"])
    assert settings["denoising"] is False and settings["adaptive_sampling"] is False
    assert settings["max_bounces"] == 64 and settings["sample_clamp_indirect"] == 0
