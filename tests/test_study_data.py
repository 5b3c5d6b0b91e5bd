"""examples/study_data.py: the brain-organoid study folder, built from a made-up checkout of the
authors' repository (a few masks whose areas say which image they are)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import tifffile

import study_data
from napari_pfsdm.errors import InputError

SHAPES = {"LabA": (40, 50), "LabB": (52, 60)}
DAYS = [(2, ""), (12, "after_embedding"), (12, "before_embedding"), (30, "")]  # not in order


def _mask(lab: str, index: int, pieces: int = 1) -> np.ndarray:
    """A square of side 4 + index (its area says which image it is), plus a 2x2 speck."""
    mask = np.zeros(SHAPES[lab], bool)
    mask[5:9 + index, 5:9 + index] = True
    if pieces == 2:
        mask[-4:-2, -4:-2] = True
    return mask


def _fake_clone(tmp_path):
    """A work tree with model_predictions/segformer/*.npy, df_pred.csv and LICENSE: organoids
    1 and 2 (clone wt2D) and 17 (clone TH2-7); organoid 2 lacks LabA's day 12 after embedding."""
    clone = tmp_path / "clone"
    folder = clone / "model_predictions" / "segformer"
    folder.mkdir(parents=True)
    (clone / "LICENSE").write_text("MIT License\n\nCopyright (c) 2023 Luca Deininger\n")
    rows, truth = [], {}
    for organoid, clone_name in ((1, "wt2D"), (2, "wt2D"), (17, "TH2-7")):
        for lab in SHAPES:
            for index, (day, stage) in enumerate(DAYS):
                if organoid == 2 and lab == "LabA" and stage == "after_embedding":
                    continue
                name = f"org{organoid:02d}_{clone_name}_d{day:02d}_{lab}"
                name += f"_{stage}" if stage else ""
                mask = _mask(lab, index, pieces=2 if (organoid, day) == (17, 30) else 1)
                np.save(folder / f"{name}.npy", mask)
                truth[name] = mask
                rows.append({"org_id": organoid, "img_id": name, "Day": day,
                             "Clone": clone_name, "Imaging": lab,
                             "org_size_px2": int(mask.sum()) + 3,
                             "pred_SegFormer_org_size": int(mask.sum()),
                             "pred_SegFormer_dice": 0.9})
    pd.DataFrame(rows).to_csv(clone / "df_pred.csv", index=False)
    return clone, truth


@pytest.fixture
def source(tmp_path):
    clone, truth = _fake_clone(tmp_path)
    made = study_data.import_clone(clone, tmp_path / "source")
    assert made == {"masks": len(truth), "pieces": 2, "border": 0}
    return tmp_path / "source", truth


def test_source_keeps_every_mask_unchanged(source):
    folder, truth = source
    for lab in SHAPES:
        stored = np.load(folder / f"segformer_{lab}.npz")
        names = [n for n in truth if f"_{lab}" in n]
        assert sorted(stored.files) == sorted(names)
        for name in names:
            assert stored[name].dtype == bool and np.array_equal(stored[name], truth[name])
    text = (folder / "README.md").read_text()
    assert "MIT" in text and "Luca Deininger" in (folder / "LICENSE").read_text()


def test_movies_in_time_order_with_pixel_size_and_times(source, tmp_path):
    folder, truth = source
    built = study_data.build_study(tmp_path / "study", folder)
    out = tmp_path / "study"
    # day 2, day 12 before embedding, day 12 after embedding, day 30: the squares' sides are
    # 4, 6, 5, 7 (index in DAYS + 4)
    for lab, pixels_per_500um in (("LabA", 158), ("LabB", 167)):
        with tifffile.TiffFile(out / lab / "org01.tif") as tif:
            movie = tif.asarray()
            assert tif.series[0].axes == "TYX" and movie.dtype == np.uint8
            assert tif.imagej_metadata["unit"] == "um"
            assert tif.pages[0].resolution == pytest.approx((pixels_per_500um / 500,) * 2)
            assert tif.imagej_metadata["Labels"][1] == "day 12, before embedding"
        assert [int(np.sqrt(f.sum())) for f in movie] == [4, 6, 5, 7]
        assert set(np.unique(movie)) == {0, 1}
    times = pd.read_csv(out / "LabA" / "times.csv")
    assert times[times.movie == "org01.tif"]["time"].tolist() == [2, 12, 12, 30]
    assert times[times.movie == "org02.tif"]["time"].tolist() == [2, 12, 30]  # one missing
    assert tifffile.imread(out / "LabA" / "org02.tif").shape == (3, *SHAPES["LabA"])
    groups = pd.read_csv(out / "groups.csv")
    assert groups.to_dict("list") == {"movie": ["org01.tif", "org02.tif", "org17.tif"],
                                      "clone": ["wt2D", "wt2D", "TH2-7"]}
    assert built["frames"] == len(truth) and (out / "LICENSE").is_file()


def test_reference_areas_in_square_microns(source, tmp_path):
    folder, _ = source
    study_data.build_study(tmp_path / "study", folder, labs=["LabB"])
    ref = pd.read_csv(tmp_path / "study" / "reference_areas.csv", keep_default_na=False)
    assert set(ref["lab"]) == {"LabB"}
    row = ref[(ref.movie == "org17.tif") & (ref.day == 30)].iloc[0]
    assert (row.pixels, row.pieces, row.largest_piece_pixels) == (7 * 7 + 4, 2, 49)
    assert row.area_um2 == pytest.approx(53 * (500 / 167) ** 2)
    assert row.manual_area_um2 == pytest.approx(56 * (500 / 167) ** 2)


def test_per_clone_keeps_the_first_organoids(source, tmp_path):
    folder, _ = source
    study_data.build_study(tmp_path / "study", folder, per_clone=1)
    assert sorted(p.name for p in (tmp_path / "study" / "LabA").glob("*.tif")) == [
        "org01.tif", "org17.tif"]


def test_plain_errors(tmp_path, capsys):
    with pytest.raises(InputError, match="--from-clone"):
        study_data.build_study(tmp_path / "study", tmp_path / "nothing")
    assert study_data.main(["--source", str(tmp_path / "nothing"),
                            "--out", str(tmp_path / "s")]) == 2
    assert "not set up" in capsys.readouterr().err
    with pytest.raises(InputError, match="not a checkout"):
        study_data.import_clone(tmp_path, tmp_path / "source")


def test_a_mask_that_is_not_the_one_counted_is_refused(tmp_path):
    clone, _ = _fake_clone(tmp_path)
    table = pd.read_csv(clone / "df_pred.csv")
    table.loc[0, "pred_SegFormer_org_size"] += 1
    table.to_csv(clone / "df_pred.csv", index=False)
    with pytest.raises(InputError, match="not the mask df_pred.csv counts"):
        study_data.import_clone(clone, tmp_path / "source")
