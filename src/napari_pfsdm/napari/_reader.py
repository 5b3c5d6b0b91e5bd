"""The plugin's reader: label images from TIFF and Zarr files opened as napari Labels layers.

napari's own reader opens a label TIFF as an Image layer (grey, contrast 0–255 on small ids:
black). Declared in ``napari.yaml`` (``readers``), this one is offered for ``.tif``, ``.tiff``
and ``.zarr`` by napari's File ▸ Open and drag and drop, under the plugin's name ("PF-SDM
morphometrics" in napari's choice of reader; tick "Remember" to keep it): it opens images of
whole numbers as Labels layers (an OME-Zarr's levels as one multiscale layer), and declines
anything else (napari's own reader then opens it).

Examples
--------
>>> import tempfile, tifffile
>>> path = tempfile.mkdtemp() + "/mask.tif"
>>> tifffile.imwrite(path, np.array([[0, 1], [2, 2]], np.uint16))
>>> [(data.tolist(), meta["name"], kind) for data, meta, kind in get_reader(path)(path)]
[([[0, 1], [2, 2]], 'mask', 'labels')]
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

#: File name endings the reader is offered for (``napari.yaml`` declares the same).
SUFFIXES = (".tif", ".tiff", ".zarr")


def get_reader(path):
    """The reader of ``path`` (one file or Zarr folder of whole numbers), or None."""
    if isinstance(path, (list, tuple)):
        if len(path) != 1:
            return None  # a stack of files is napari's to join
        path = path[0]
    path = Path(path)
    if path.suffix.lower() not in SUFFIXES:
        return None
    try:
        levels, _scale = _levels(path)
    except (OSError, ValueError, KeyError, TypeError):
        return None  # not a file this reader understands: napari's own tries
    dtype = np.dtype(levels[0].dtype)
    if not (np.issubdtype(dtype, np.integer) or dtype == np.bool_):
        return None
    return read_labels


def read_labels(path) -> list[tuple]:
    """napari layer data of the label image in ``path``: one Labels layer named after the file
    (every level of an OME-Zarr, finest first, as a multiscale layer)."""
    path = Path(path[0] if isinstance(path, (list, tuple)) else path)
    levels, scale = _levels(path)
    name = path.name[: -len(path.suffix)] if path.suffix else path.name
    meta = {"name": name, "metadata": {"source_path": str(path)}}
    if scale is not None:
        meta["scale"] = scale
    meta = _with_calibration(path, levels[0], meta)
    if len(levels) > 1:
        return [(levels, {**meta, "multiscale": True}, "labels")]
    data = levels[0]
    if isinstance(data, np.ndarray) and data.dtype == np.bool_:
        data = data.astype(np.uint8)  # napari's Labels want whole numbers
    return [(data, meta, "labels")]


def _with_calibration(path: Path, data, meta: dict) -> dict:
    """``meta`` with the pixel size (``scale``, ``units``) and the frames' times
    (``metadata["times"]``, ``["time_unit"]``) that the file declares
    (:func:`napari_pfsdm.io.metadata.read_metadata`): a 3-D file is a time-lapse, a 4-D
    one a time-lapse of Z-stacks (the analysis panel's defaults)."""
    from ..io.metadata import read_metadata

    ndim = len(data.shape)
    if ndim < 2:
        return meta
    n_frames = data.shape[0] if ndim >= 3 else 1
    found = read_metadata(path, n_frames, volume=ndim == 4)
    meta = {**meta, "metadata": dict(meta["metadata"])}
    if found.pixel_size is not None and "scale" not in meta:
        size = list(found.pixel_size)
        meta["scale"] = [1.0] * (ndim - len(size)) + size
        if found.space_unit:
            unit = {"µm": "micrometer", "nm": "nanometer", "mm": "millimeter",
                    "cm": "centimeter", "m": "meter"}[found.space_unit]
            meta["units"] = ["pixel"] * (ndim - len(size)) + [unit] * len(size)
    if found.times is not None and ndim >= 3:
        meta["metadata"]["times"] = list(found.times)
        meta["metadata"]["time_unit"] = found.time_unit
    return meta


def _levels(path: Path) -> tuple[list, list | None]:
    """The arrays of ``path`` (a TIFF read at once; a Zarr array, or an OME-Zarr's levels,
    read lazily) and the finest level's scale when the file declares one."""
    if path.suffix.lower() in (".tif", ".tiff"):
        import tifffile

        return [tifffile.imread(path)], None
    import zarr

    node = zarr.open(str(path), mode="r")
    if hasattr(node, "dtype"):
        return [node], None
    multiscales = node.attrs.get("multiscales") or []
    if not multiscales:
        raise ValueError(f"{path} is a Zarr group without multiscales")
    datasets = multiscales[0]["datasets"]
    scale = None
    for transform in datasets[0].get("coordinateTransformations", []):
        if transform.get("type") == "scale":
            scale = [float(v) for v in transform["scale"]]
    return [node[d["path"]] for d in datasets], scale
