"""A finished Run, or an analysis opened from a folder, becomes its layer's analysis in the
plugin's model, whether or not the dock that started it is still open."""

from __future__ import annotations

from napari.utils.notifications import show_info, show_warning

from ._model import REGISTRY, Analysis, current_frame


def layer_data(layer):
    """A layer's data at full resolution (the first level of a multiscale one)."""
    return layer.data[0] if getattr(layer, "multiscale", False) else layer.data


def store_run(viewer, labels, seconds: float | None, fields: dict) -> Analysis | None:
    """A finished Run (``seconds`` long; None: opened from a folder) becomes the layer's
    analysis, whether or not a dock is still open: the model writes the layer's features;
    napari selects an object that has pictures."""
    if labels not in viewer.layers:
        show_warning("PF-SDM: the Labels layer was removed during the run; nothing was kept.")
        return None
    n = len(fields["table"])
    took = f" in {seconds:.1f} s" if seconds is not None else ""
    fields["message"] = f"{n:,} objects{took}. {fields['message']}"
    if "groups" not in fields:  # a run: the layer's own groups (e.g. the sample's)
        groups = labels.metadata.get("groups") or {}
        fields["groups"] = {int(k): str(v) for k, v in groups.items()}
    analysis = REGISTRY.new_run(labels, fields, viewer)
    warn = analysis.tracking_message.startswith("Warning")
    (show_warning if warn else show_info)(f"PF-SDM: {n:,} objects measured.")
    frame = current_frame(viewer.dims, labels, analysis.time_lapse)
    present = [lab for lab in analysis.labels_in(frame) if not analysis.error_of(frame, lab)]
    if labels.selected_label not in present and present:  # an object with pictures
        labels.selected_label = int(present[0])
    analysis.select(frame, labels.selected_label)
    return analysis
