"""The fault battery, round 3 (issue 66), rules 6 and 8: what the file holds, and refusals
that name the file or option and say what to do.

Compressed TIFFs read as tifffile reads them; a raw image given as labels is refused before
any work (a label image of thousands of objects is not); a reporter's channel is read as the
napari plugin offers it; negative ids, labels and reporter of other shapes and a full disk are
refused naming the file and the fix. Expected values come from numpy, scikit-image and
tifffile.
"""

from __future__ import annotations

import errno
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import tifffile
from skimage import data, filters, measure, segmentation

import napari_pfsdm as pf
from napari_pfsdm.cli import main
from napari_pfsdm.errors import InputError
from shapes_fixture import drifting_ellipses

FAST = {"n_fourier": 4, "n_radii": 4}
CLI_FAST = ["--n-fourier", "4", "--n-radii", "4", "--link", "labels", "-q", "--scheduler",
            "sync"]


def error_line(capsys) -> str:
    err = capsys.readouterr().err
    assert "Traceback" not in err and "internal error" not in err, err
    lines = [ln for ln in err.splitlines() if ln.startswith("pfsdm: error:")]
    assert len(lines) == 1, err
    return lines[0]


def ellipses(n_frames: int = 3, n: int = 6) -> np.ndarray:
    return drifting_ellipses(n_frames, n)


def features(table: pd.DataFrame, channel: str) -> np.ndarray:
    return table[[c for c in table.columns if c.startswith(f"{channel}_")]].to_numpy(float)


# --------------------------------------------------------------------------------------------
# compressed TIFFs
# --------------------------------------------------------------------------------------------

LOSSLESS = ["lzw", "zlib", "zstd", "lzma", "packbits", "png", "lerc", "jpegxl"]


@pytest.mark.parametrize("codec", LOSSLESS)
def test_compressed_label_tiffs_read_as_written(tmp_path, codec):
    labels = ellipses().astype(np.uint8 if codec in ("png", "jpegxl") else np.uint16)
    kw = {"compressionargs": {"lossless": True}} if codec == "jpegxl" else {}
    tifffile.imwrite(tmp_path / "m.tif", labels, compression=codec, photometric="minisblack",
                     **kw)
    np.testing.assert_array_equal(tifffile.imread(tmp_path / "m.tif"), labels)
    assert main(["measure", str(tmp_path / "m.tif"), "-o", str(tmp_path / "f.csv"),
                 *CLI_FAST]) == 0
    got = pf.read_table(tmp_path / "f.csv")
    want = pf.measure(labels, **FAST)
    np.testing.assert_array_equal(got["label"], want["label"])
    np.testing.assert_allclose(features(got, "shape"), features(want, "shape"), rtol=0,
                               atol=1e-12)


def test_a_jpeg_reporter_reads_as_tifffile_decodes_it(tmp_path):
    labels = ellipses()
    rng = np.random.default_rng(0)
    reporter = (filters.gaussian(rng.random(labels.shape), 2) * 255).astype(np.uint8)
    tifffile.imwrite(tmp_path / "m.tif", labels, photometric="minisblack")
    tifffile.imwrite(tmp_path / "r.tif", reporter, compression="jpeg",
                     photometric="minisblack")
    decoded = tifffile.imread(tmp_path / "r.tif")
    assert main(["measure", str(tmp_path / "m.tif"), "-i", str(tmp_path / "r.tif"), "-o",
                 str(tmp_path / "f.csv"), *CLI_FAST]) == 0
    want = pf.measure(labels, decoded, **FAST)
    np.testing.assert_allclose(features(pf.read_table(tmp_path / "f.csv"), "intensity"),
                               features(want, "intensity"), rtol=0, atol=1e-12)


def test_imagecodecs_is_part_of_the_core_install():
    import tomllib

    project = tomllib.loads((Path(__file__).parents[1] / "pyproject.toml").read_text())
    assert any(d.split(">")[0].strip() == "imagecodecs"
               for d in project["project"]["dependencies"])


@pytest.mark.parametrize("codec", ["lzw", "jpeg", "zstd"])
def test_without_imagecodecs_a_compressed_tiff_is_not_called_damaged(tmp_path, codec):
    labels = ellipses().astype(np.uint8)
    tifffile.imwrite(tmp_path / "m.tif", labels, compression=codec, photometric="minisblack")
    code = textwrap.dedent(f"""
        import sys
        sys.modules["imagecodecs"] = None  # as an install without it
        from napari_pfsdm.cli import main
        sys.exit(main(["measure", {str(tmp_path / "m.tif")!r}, "-o",
                       {str(tmp_path / "f.csv")!r}, "-q", "--scheduler", "sync"]))
    """)
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=300)
    assert run.returncode == 2, run.stderr
    assert "needs the imagecodecs package" in run.stderr and "pip install imagecodecs" \
        in run.stderr and "damaged or truncated" not in run.stderr
    assert not (tmp_path / "f.csv").exists()


# --------------------------------------------------------------------------------------------
# a raw image given as labels
# --------------------------------------------------------------------------------------------

def nuclei(n: int = 3600, size: int = 2048, seed: int = 0) -> np.ndarray:
    """About 3,500 nuclei (radius 6-14 pixels, touching) with their own ids, in a frame."""
    rng = np.random.default_rng(seed)
    out = np.zeros((size, size), np.uint32)
    cy, cx = rng.uniform(0, size, n), rng.uniform(0, size, n)
    r = rng.uniform(6, 14, n)
    k = 0
    for y, x, rad in zip(cy, cx, r, strict=True):
        y0, y1 = int(max(y - rad, 0)), int(min(y + rad + 1, size))
        x0, x1 = int(max(x - rad, 0)), int(min(x + rad + 1, size))
        yy, xx = np.mgrid[y0:y1, x0:x1]
        free = ((yy - y) ** 2 + (xx - x) ** 2 < rad**2) & (out[y0:y1, x0:x1] == 0)
        if free.sum() > 20:
            k += 1
            out[y0:y1, x0:x1][free] = k
    return out


def microscope(labels: np.ndarray, seed: int = 0) -> np.ndarray:
    """A 16-bit fluorescence image of ``labels``: blurred, an offset, shot noise."""
    rng = np.random.default_rng(seed)
    blur = filters.gaussian((labels > 0).astype(float), 2)
    return rng.poisson(100 + 2000 * blur).astype(np.uint16)


@pytest.fixture(scope="module")
def cells():
    return nuclei()


def raw_images(cells) -> dict[str, np.ndarray]:
    small = cells[:512, :512]
    micro = microscope(small)
    return {"16-bit microscope image": micro,
            "16-bit, background subtracted": np.clip(micro.astype(int) - 400, 0,
                                                     None).astype(np.uint16),
            "8-bit coins": data.coins(),
            "8-bit camera": data.camera(),
            "a movie whose middle frame is raw": np.stack([small.astype(np.uint16), micro,
                                                           small.astype(np.uint16)])}


def test_a_raw_image_given_as_labels_is_refused_before_any_work(cells, tmp_path, capsys):
    for name, image in raw_images(cells).items():
        path = tmp_path / "raw.tif"
        tifffile.imwrite(path, image, photometric="minisblack")
        out = tmp_path / "f.csv"
        assert main(["measure", str(path), "-o", str(out), *CLI_FAST]) == 2, name
        line = error_line(capsys)
        assert "raw.tif looks like a raw image, not a label image" in line, (name, line)
        assert "Give the segmentation (one whole number per object, 0 = background)" in line
        assert not out.exists() and not any((tmp_path / "f.csv.parts").glob("*")), name
        with pytest.raises(InputError, match="like a raw image"):  # Python, and the plugin's
            pf.measure(image, **FAST)                              # count of objects
        from napari_pfsdm.analysis.label_images import count_objects

        with pytest.raises(InputError, match="like a raw image"):
            count_objects(image)


def test_label_images_of_many_objects_are_not_refused(cells, tmp_path):
    from napari_pfsdm.analysis.label_images import count_objects, raw_image_reason

    rng = np.random.default_rng(1)
    markers = np.zeros((512, 512), int)
    pts = rng.integers(0, 512, (800, 2))
    markers[pts[:, 0], pts[:, 1]] = np.arange(1, 801)
    tessellation = segmentation.watershed(filters.gaussian(rng.random((512, 512)), 3), markers)
    coins = data.coins()
    pieces = np.zeros((64, 300), np.int8)  # every object in three pieces
    for i in range(20):
        pieces[5:9, 15 * i:15 * i + 3] = pieces[20:24, 15 * i:15 * i + 3] = \
            pieces[40:44, 15 * i:15 * i + 3] = i + 1
    labels = {"3,500 nuclei": cells, "a tessellation (no background)": tessellation,
              "coins segmented": measure.label(coins > filters.threshold_otsu(coins)),
              "int8, in pieces": pieces, "a mask": cells > 0}
    for name, image in labels.items():
        assert raw_image_reason(image) is None, name
    assert count_objects(cells) == len(np.unique(cells)) - 1 > 3000
    tifffile.imwrite(tmp_path / "n.tif", cells, photometric="minisblack")
    from napari_pfsdm.batch.io import check_labels, open_movie

    check_labels(open_movie(tmp_path / "n.tif"), where="n.tif")  # what measure checks first


def test_negative_ids_are_refused_naming_the_file_and_the_fix(tmp_path, capsys):
    labels = ellipses(4).astype(np.int16)
    for frame in (0, 1):  # 1: not among the frames checked first; said while measuring
        bad = labels.copy()
        bad[frame, 0, 0] = -1
        tifffile.imwrite(tmp_path / "neg.tif", bad, photometric="minisblack")
        assert main(["measure", str(tmp_path / "neg.tif"), "-o", str(tmp_path / "f.csv"),
                     *CLI_FAST]) == 2
        line = error_line(capsys)
        assert "neg.tif" in line and "negative" in line, line
        if frame == 0:
            assert "set them to 0" in line and "skimage.measure.label" in line
        assert not (tmp_path / "f.csv").exists()


# --------------------------------------------------------------------------------------------
# a reporter's channels, as the plugin offers them
# --------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def channels(tmp_path_factory):
    folder = tmp_path_factory.mktemp("channels")
    labels = ellipses()
    rng = np.random.default_rng(0)
    stack = np.stack([filters.gaussian(rng.random(labels.shape), 1 + k).astype(np.float32)
                      * (k + 1) for k in range(4)], axis=1)  # T, C, Y, X
    tifffile.imwrite(folder / "m.tif", labels, photometric="minisblack")
    tifffile.imwrite(folder / "imagej.tif", stack, imagej=True, metadata={"axes": "TCYX"})
    tifffile.imwrite(folder / "ome.ome.tif", stack, metadata={"axes": "TCYX"})
    tifffile.imwrite(folder / "plain.tif", stack, photometric="minisblack")  # axes unnamed
    tifffile.imwrite(folder / "ambiguous.tif", stack[:, :3], photometric="minisblack")
    zarr = pytest.importorskip("zarr")
    arr = zarr.create_array(str(folder / "r.zarr"), shape=stack.shape, dtype=stack.dtype,
                            chunks=(1, 1, 96, 160), dimension_names=["t", "c", "y", "x"])
    arr[:] = stack
    return folder, labels, stack


@pytest.mark.parametrize("reporter", ["imagej.tif", "ome.ome.tif", "plain.tif", "r.zarr"])
def test_the_reporters_channel_is_read_as_the_plugin_offers_it(channels, tmp_path, capsys,
                                                              reporter):
    from napari_pfsdm.analysis.label_images import reporter_channels

    folder, labels, stack = channels
    assert reporter_channels(stack.shape, labels.shape) == [0, 1, 2, 3]  # the plugin's offer
    for channel in (1, 3):
        out = tmp_path / f"f{channel}.csv"
        assert main(["measure", str(folder / "m.tif"), "-i", str(folder / reporter), "-o",
                     str(out), "--reporter-channel", str(channel), *CLI_FAST]) == 0, \
            capsys.readouterr().err
        want = pf.measure(labels, stack[:, channel], **FAST)
        np.testing.assert_allclose(features(pf.read_table(out), "intensity"),
                                   features(want, "intensity"), rtol=0, atol=1e-12)
    # without the option, or with a channel it does not have: refused, saying which to give
    assert main(["measure", str(folder / "m.tif"), "-i", str(folder / reporter), "-o",
                 str(tmp_path / "g.csv"), *CLI_FAST]) == 2
    assert "has 4 channels: say which one is the reporter with --reporter-channel N (0 to 3" \
        in error_line(capsys)
    assert main(["measure", str(folder / "m.tif"), "-i", str(folder / reporter), "-o",
                 str(tmp_path / "g.csv"), "--reporter-channel", "4", *CLI_FAST]) == 2
    assert "--reporter-channel 4:" in error_line(capsys)


def test_a_channel_the_file_cannot_tell_from_time_or_a_reporter_without_channels(channels,
                                                                                   tmp_path,
                                                                                   capsys):
    folder, labels, stack = channels
    assert main(["measure", str(folder / "m.tif"), "-i", str(folder / "ambiguous.tif"), "-o",
                 str(tmp_path / "f.csv"), "--reporter-channel", "1", *CLI_FAST]) == 2
    assert "axis 0 or axis 1 could be its channels" in error_line(capsys)
    tifffile.imwrite(tmp_path / "one.tif", stack[:, 0], photometric="minisblack")
    assert main(["measure", str(folder / "m.tif"), "-i", str(tmp_path / "one.tif"), "-o",
                 str(tmp_path / "f.csv"), "--reporter-channel", "0", *CLI_FAST]) == 2
    assert "has no axis of channels" in error_line(capsys)


def test_another_channel_is_measured_again_not_resumed(channels, tmp_path):
    folder, labels, stack = channels
    out = tmp_path / "f.csv"
    for channel in (0, 2):
        assert main(["measure", str(folder / "m.tif"), "-i", str(folder / "imagej.tif"), "-o",
                     str(out), "--reporter-channel", str(channel), *CLI_FAST]) == 0
        want = pf.measure(labels, stack[:, channel], **FAST)
        np.testing.assert_allclose(features(pf.read_table(out), "intensity"),
                                   features(want, "intensity"), rtol=0, atol=1e-12)


# --------------------------------------------------------------------------------------------
# refusals that name the file and the fix
# --------------------------------------------------------------------------------------------

def test_labels_and_reporter_of_other_shapes_are_named(tmp_path, capsys):
    labels = ellipses()
    tifffile.imwrite(tmp_path / "m.tif", labels, photometric="minisblack")
    tifffile.imwrite(tmp_path / "r.tif", np.zeros((3, 96, 150), np.float32),
                     photometric="minisblack")
    assert main(["measure", str(tmp_path / "m.tif"), "-i", str(tmp_path / "r.tif"), "-o",
                 str(tmp_path / "f.csv"), *CLI_FAST]) == 2
    line = error_line(capsys)
    assert "m.tif" in line and "r.tif" in line and "(3, 96, 160) and (3, 96, 150)" in line
    assert "Give the reporter recorded with these labels" in line


def test_a_full_disk_names_the_file_and_what_to_do(tmp_path, monkeypatch, capsys):
    import os

    labels = ellipses()
    tifffile.imwrite(tmp_path / "m.tif", labels, photometric="minisblack")
    out = tmp_path / "f.csv"
    assert main(["measure", str(tmp_path / "m.tif"), "-o", str(out), *CLI_FAST]) == 0
    kept = out.read_bytes()
    real = os.fsync

    def full(fd):  # the disk fills while the table is written
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "fsync", full)
    assert main(["trajectories", str(out), "-o", str(tmp_path / "p.csv"), "-q"]) == 2
    line = error_line(capsys)
    assert "p.csv: cannot write it: No space left on device; the disk is full: free some " \
           "space, or write to another disk" in line, line
    assert not (tmp_path / "p.csv").exists()
    assert list(tmp_path.glob(".*.tmp")) == []
    with pytest.raises(OSError, match="p.csv"):  # Python: the same words, an OSError still
        pf.write_table(pf.read_table(out), tmp_path / "p.csv")
    monkeypatch.setattr(os, "fsync", real)
    assert out.read_bytes() == kept
