"""Every column napari-pfsdm writes has a meaning in plain words (the export's glossary)."""

from __future__ import annotations

import numpy as np

import napari_pfsdm as pf
from napari_pfsdm.analysis.glossary import describe_column
from napari_pfsdm.analysis.reduction import pca_scores
from napari_pfsdm.data.gastruloids import make_timelapse_montage
from napari_pfsdm.data.volumes import blob_volume


def test_every_column_of_a_measured_table_has_a_meaning():
    labels, reporter, _ = make_timelapse_montage(seed=0)
    table = pf.link(pf.measure(labels[:3], reporter[:3]))
    scores, _ = pca_scores(table, "shape", 3)
    columns = [*table.columns, *scores.columns, "p_multi-axes", "failed", "index"]
    missing = [c for c in columns if not describe_column(c)]
    assert missing == []


def test_every_column_of_a_3d_table_has_a_meaning():
    volume = blob_volume("tetrahedron", size=(20, 32, 32), radius=8)
    table = pf.measure(volume.astype(np.uint8), axes="zyx")
    assert [c for c in table.columns if not describe_column(c)] == []


def test_the_words_name_the_numbers_in_the_column():
    assert "ring 3" in describe_column("intensity_r03_n12") and "|c_12|" in \
        describe_column("intensity_r03_n12")
    assert "index -5, real part" in describe_column("outline_n-05_re")
    assert "group 'multi-axes'" in describe_column("p_multi-axes")
    assert "piece 3 of" in describe_column("width_b03") and "pixels" in describe_column("width_b03")
    assert "piece 12 of" in describe_column("reporter_b12")
    assert "component 2 of the intensity" in describe_column("intensity_PC2")
    assert describe_column("someone's own column") == ""


def test_docs_columns_md_is_made_from_the_declarations():
    """docs/columns.md is the glossary's own page: a column declared by a measure appears
    there with its meaning and unit, none is written twice."""
    from pathlib import Path

    from napari_pfsdm.analysis.glossary import columns_markdown

    page = Path(__file__).parents[1] / "docs" / "columns.md"
    assert page.read_text() == columns_markdown(), (
        "docs/columns.md differs from the declarations: write it with "
        "napari_pfsdm.analysis.glossary.columns_markdown()")
    assert "| `perimeter` | perimeter (scikit-image's regionprops) | pixels (or unit) |" in \
        columns_markdown()


def test_sizes_say_their_unit():
    assert describe_column("area") == "area of the object's labelled pixels (pixels)"
    assert describe_column("area", space_unit="µm").endswith("(µm²)")
    assert describe_column("midline_length", space_unit="µm").endswith("(µm)")
    assert describe_column("volume", space_unit="µm").endswith("(µm³)")
    assert describe_column("time", time_unit="day").endswith("(day)")
    assert describe_column("shape_r00_n00", space_unit="µm").endswith("(0: mean: thickness)")
    assert describe_column("centroid_x", space_unit="µm").endswith("(pixels)")
