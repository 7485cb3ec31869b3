"""What map_server / map_saver write: P5 with comments, 16-bit PGM, PNG and colour images, optional
negate, modes trinary / scale / raw, .yml, rotated origins."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from PIL import Image

from filters.mapping.grid import GridMap
from filters.mapping.ros_map import (
    MapFormatError,
    MapFormatWarning,
    load_map,
    read_map_image,
    read_pgm,
    save_map,
    unknown_occupancy,
)

TOP_FIRST = np.array([[0, 254, 205, 255], [254, 254, 0, 100], [0, 0, 0, 254]], dtype=np.uint8)
TRINARY_BOTTOM_FIRST = np.array([[1.0, 1.0, 1.0, 0.0], [0.0, 0.0, 1.0, 0.5], [1.0, 0.0, 0.5, 0.0]])


def _yaml(folder, image, extra="", suffix=".yaml"):
    path = folder / f"m{suffix}"
    path.write_text(
        f"image: {image}\nresolution: 0.05\norigin: [1.0, -2.0, 0.0]\n"
        f"occupied_thresh: 0.65\nfree_thresh: 0.196\n{extra}\n"
    )
    return path


def test_p5_with_comments_everywhere(tmp_path):
    body = TOP_FIRST.tobytes()
    (tmp_path / "a.pgm").write_bytes(b"P5\n# CREATOR: map_saver.cpp 0.050 m/pix\n4 # width\n3\n# max\n255\n" + body)
    grid = load_map(_yaml(tmp_path, "a.pgm"))
    np.testing.assert_array_equal(grid.occupancy, TRINARY_BOTTOM_FIRST)
    assert grid.origin_xy_m == (1.0, -2.0)


def test_16_bit_pgm_reads_like_the_8_bit_one(tmp_path):
    wide = (TOP_FIRST.astype(np.uint16) * 257).astype(">u2")  # 255 -> 65535: the same grey levels
    (tmp_path / "w.pgm").write_bytes(b"P5\n4 3\n65535\n" + wide.tobytes())
    grid = load_map(_yaml(tmp_path, "w.pgm", "mode: scale"))
    ref = (255.0 - TOP_FIRST[::-1].astype(np.float64)) / 255.0
    np.testing.assert_allclose(grid.occupancy, ref, atol=1e-6)
    grey, alpha = read_map_image(tmp_path / "w.pgm")
    np.testing.assert_allclose(grey, TOP_FIRST, atol=1e-9)
    assert alpha is None
    with pytest.raises(MapFormatError, match="read_map_image"):
        read_pgm(tmp_path / "w.pgm")


@pytest.mark.parametrize("kind", ["L", "RGB", "LA", "I;16", "P"])
def test_png_images(tmp_path, kind):
    if kind == "L":
        im = Image.fromarray(TOP_FIRST)
    elif kind == "RGB":
        im = Image.fromarray(np.repeat(TOP_FIRST[..., None], 3, axis=2))
    elif kind == "LA":  # transparent: (3 g + 0) / 4 in trinary mode, below (the opaque case)
        im = Image.fromarray(np.stack([TOP_FIRST, np.full_like(TOP_FIRST, 255)], axis=2))
        im.save(tmp_path / "m.png")
        np.testing.assert_array_equal(load_map(_yaml(tmp_path, "m.png", "mode: scale")).occupancy == 1.0,
                                      TRINARY_BOTTOM_FIRST == 1.0)  # fmt: skip
        return
    elif kind == "I;16":
        im = Image.fromarray(TOP_FIRST.astype(np.uint16) * 257)
    else:
        im = Image.fromarray(TOP_FIRST).convert("P")
    im.save(tmp_path / "m.png")
    grid = load_map(_yaml(tmp_path, "m.png"))
    np.testing.assert_array_equal(grid.occupancy, TRINARY_BOTTOM_FIRST)


def test_colour_pixels_average_their_channels_and_transparency_is_unknown_in_scale_mode(tmp_path):
    rgba = np.zeros((1, 3, 4), np.uint8)
    rgba[0, 0] = (255, 255, 255, 255)  # white: free
    rgba[0, 1] = (255, 0, 0, 255)  # mean 85: p = 0.667 > 0.65: occupied
    rgba[0, 2] = (128, 128, 128, 0)  # transparent grey, between the thresholds
    Image.fromarray(rgba).save(tmp_path / "c.png")
    grid = load_map(_yaml(tmp_path, "c.png", "mode: scale"))
    np.testing.assert_allclose(grid.occupancy[0], [0.0, 170 / 255, 0.5], atol=1e-6)
    assert grid.occupied_mask()[0].tolist() == [False, True, False]


def test_negate_is_optional_and_defaults_to_0(tmp_path):
    Image.fromarray(TOP_FIRST).save(tmp_path / "m.png")
    plain = load_map(_yaml(tmp_path, "m.png"))
    explicit = load_map(_yaml(tmp_path, "m.png", "negate: 0"))
    negated = load_map(_yaml(tmp_path, "m.png", "negate: 1"))
    np.testing.assert_array_equal(plain.occupancy, explicit.occupancy)
    assert negated.occupancy[2, 0] == 0.0 and plain.occupancy[2, 0] == 1.0  # black: occupied / free


def test_raw_mode(tmp_path):
    img = np.array([[0, 50, 100, 101, 255]], np.uint8)
    Image.fromarray(img).save(tmp_path / "r.png")
    grid = load_map(_yaml(tmp_path, "r.png", "mode: raw"))
    np.testing.assert_allclose(grid.occupancy[0], [0.0, 0.5, 1.0, 0.5, 0.5])
    neg = load_map(_yaml(tmp_path, "r.png", "mode: raw\nnegate: 1"))  # map_server negates before raw
    np.testing.assert_allclose(neg.occupancy[0], [0.5, 0.5, 0.5, 0.5, 0.0])


def test_yml_everywhere(tmp_path):
    grid = GridMap(np.array([[0.0, 1.0], [0.5, 0.0]], np.float32), 0.1, (2.0, 3.0))
    path = save_map(grid, tmp_path / "x.yml")
    assert path.suffix == ".yml" and (tmp_path / "x.pgm").is_file()
    back = load_map(path)
    np.testing.assert_array_equal(back.occupancy, grid.occupancy)
    Image.fromarray(TOP_FIRST).save(tmp_path / "m.png")
    assert load_map(_yaml(tmp_path, "m.png", suffix=".yml")).shape == (3, 4)


def test_rotated_origin_is_refused_with_a_clear_error(tmp_path):
    Image.fromarray(TOP_FIRST).save(tmp_path / "m.png")
    path = tmp_path / "rot.yaml"
    path.write_text(
        "image: m.png\nresolution: 0.05\norigin: [0.0, 0.0, 1.5708]\noccupied_thresh: 0.65\nfree_thresh: 0.2\n"
    )
    with pytest.raises(MapFormatError, match="origin yaw is 1.5708 rad; rotated maps are not supported") as e:
        load_map(path)
    assert e.value.path == str(path)


def test_a_key_given_twice_in_the_yaml_is_refused_naming_both_lines(tmp_path):
    grid = GridMap(np.array([[0.0, 1.0], [0.5, 0.0]], np.float32), 0.1, (2.0, 3.0))
    path = save_map(grid, tmp_path / "x.yaml")
    assert load_map(path).resolution_m == 0.1
    lines = path.read_text().splitlines()
    first = next(i for i, line in enumerate(lines) if line.startswith("resolution:")) + 1
    path.write_text(path.read_text() + "resolution: 0.5\n")  # PyYAML alone would take 0.5 m cells silently
    with pytest.raises(
        MapFormatError, match=rf"line {len(lines) + 1}: key 'resolution' given twice .*first on line {first}"
    ):
        load_map(path)


def test_undecodable_image(tmp_path):
    (tmp_path / "m.png").write_bytes(b"\x89PNG\r\n\x1a\n" + b"\0" * 20)
    with pytest.raises(MapFormatError, match="m.png"):
        load_map(_yaml(tmp_path, "m.png"))


def test_an_oversized_png_is_a_map_format_error_naming_the_file(tmp_path, monkeypatch):
    # Pillow's own DecompressionBombError (no file name) came through before (an input audit);
    # its pixel limit is lowered here so that the test does not need a 400-megapixel image
    path = tmp_path / "big.png"
    Image.new("L", (400, 400), 255).save(path)
    monkeypatch.setattr(Image, "MAX_IMAGE_PIXELS", 1000)
    with pytest.raises(MapFormatError, match="big.png.*too large"):
        read_map_image(path)


def test_alpha_is_averaged_in_for_trinary_maps_as_map_server_does(tmp_path):
    # a twentieth tester's: transparent white read as free and opaque grey 60 as occupied; map_server and nav2
    # average alpha in for a trinary map: (r + g + b + a) / 4 (an LA image is loaded as RGBA with r = g = b)
    px = np.array([[[255, 255, 255, 0], [60, 60, 60, 255], [0, 0, 0, 255], [205, 205, 205, 255]]], np.uint8)
    Image.fromarray(px, "RGBA").save(tmp_path / "rgba.png")
    grid = load_map(_yaml(tmp_path, "rgba.png"))
    # means 191.25, 108.75, 63.75, 217.5: p = 0.25, 0.574, 0.75, 0.147
    assert grid.occupancy[0].tolist() == [0.5, 0.5, 1.0, 0.0]
    Image.fromarray(px[..., [0, 3]], "LA").save(tmp_path / "la.png")
    assert load_map(_yaml(tmp_path, "la.png")).occupancy[0].tolist() == [0.5, 0.5, 1.0, 0.0]
    # scale mode leaves alpha out of the grey, as before
    np.testing.assert_allclose(
        load_map(_yaml(tmp_path, "rgba.png", "mode: scale")).occupancy[0], [0.0, 195 / 255, 1.0, 50 / 255], atol=1e-6
    )


def test_the_registered_envs_read_alpha_maps_as_before(tmp_path):
    # a review: averaging alpha in changed SemReloc-v22's world and episodes on an RGBA map (opaque grey-60 walls
    # became unknown); the envs keep the old reading, load_map's default follows map_server
    import gymnasium as gym

    import semreloc_env  # noqa: F401

    px = np.full((120, 120, 4), 254, np.uint8)
    px[..., 3] = 255
    px[:4], px[-4:], px[:, :4], px[:, -4:] = 60, 60, 60, 60
    px[..., 3] = 255
    Image.fromarray(px, "RGBA").save(tmp_path / "room.png")
    path = _yaml(tmp_path, "room.png")
    assert load_map(path, alpha_in_trinary=False).occupied_mask().sum() > 1000
    assert load_map(path).occupied_mask().sum() == 0  # (3 * 60 + 255) / 4: p = 0.574, unknown to map_server
    env = gym.make("SemReloc-v22", map_source=str(path), semantic=False, relocalizer={"n_particles": 100})
    assert env.unwrapped.grid.occupied_mask().sum() == load_map(path, alpha_in_trinary=False).occupied_mask().sum()


@pytest.mark.parametrize("free, occ", [(0.1, 0.4), (0.6, 0.9), (0.196, 0.65), (0.3, 0.3)])
def test_unknown_cells_read_as_unknown_whatever_the_thresholds(tmp_path, free, occ):
    """An outside audit's: unknown cells were stored as 0.5, which thresholds 0.1 / 0.4 read as occupied (and a world
    built from the map made them walls), 0.6 / 0.9 as free. map_server: occupied only above occupied_thresh, free
    only below free_thresh, else unknown."""
    (tmp_path / "u.pgm").write_bytes(b"P2\n3 1\n255\n0 170 255\n")  # p = 1, 1/3, 0
    for mode in ("trinary", "raw"):
        path = _yaml(tmp_path, "u.pgm").with_name(f"{mode}.yaml")
        text = (tmp_path / "m.yaml").read_text().replace("0.65", str(occ)).replace("0.196", str(free))
        path.write_text(text + f"mode: {mode}\nnegate: 1\n" if mode == "raw" else text)
        grid = load_map(path)
        unknown = ~grid.occupied_mask() & ~grid.free_mask()
        if mode == "trinary":  # p = 1/3: free under 0.6 / 0.9, occupied under 0.3 / 0.3, else unknown
            assert grid.occupied_mask()[0].tolist() == [True, 1 / 3 > occ, False]
            assert unknown[0, 1] == (free <= 1 / 3 <= occ)
        else:  # negated: 255, 85, 0 percent -> unknown, 0.85, 0.0
            assert unknown[0, 0] and grid.occupancy[0, 0] == unknown_occupancy(free, occ)
    assert unknown_occupancy(free, occ) == (0.5 if free <= 0.5 <= occ else 0.5 * (free + occ))


def test_the_envs_reading_keeps_unknown_at_half_and_says_what_it_reads(tmp_path):
    (tmp_path / "u.pgm").write_bytes(b"P2\n3 1\n255\n0 205 254\n")
    path = _yaml(tmp_path, "u.pgm")
    path.write_text(path.read_text().replace("0.65", "0.4").replace("0.196", "0.1"))
    assert load_map(path).occupied_mask()[0].tolist() == [True, False, False]
    with pytest.warns(MapFormatWarning, match="do not straddle 0.5, so the unknown cells.*read as occupied"):
        assert load_map(path, unknown_at_half=True).occupied_mask()[0].tolist() == [True, True, False]
    path.write_text(path.read_text().replace("0.4", "0.65").replace("0.1", "0.196"))  # the defaults: no warning
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert np.array_equal(load_map(path, unknown_at_half=True).occupancy, load_map(path).occupancy)


@pytest.mark.parametrize("origin, res", [("1e300", "0.05"), ("0.0", "1e300"), ("-2e12", "0.05"), ("0.0", "1e12")])
def test_a_map_beyond_a_trillion_metres_is_a_format_error_naming_the_file(tmp_path, origin, res):
    """An outside audit's: resolution 1e300 loaded, then the env's reset raised a bare OverflowError; origin 1e300 said
    the map had no free space."""
    (tmp_path / "m.pgm").write_bytes(b"P2\n3 2\n255\n0 254 254\n254 254 0\n")
    path = tmp_path / "m.yaml"
    path.write_text(
        f"image: m.pgm\nresolution: {res}\norigin: [{origin}, 0.0, 0.0]\noccupied_thresh: 0.65\nfree_thresh: 0.196\n"
    )
    with pytest.raises(MapFormatError, match=r"m\.yaml: origin .* beyond the 1e\+12 m maps may reach"):
        load_map(path)
    path.write_text(
        path.read_text().replace(f"[{origin},", "[-9.9e11,").replace(f"resolution: {res}", "resolution: 0.05")
    )
    assert load_map(path).origin_xy_m[0] == -9.9e11
