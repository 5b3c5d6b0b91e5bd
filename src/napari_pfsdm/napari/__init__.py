"""The napari plugin: analysis dock widget, linked plots, result layers, sample data.

The only part of napari-pfsdm that imports Qt, napari or magicgui. Widgets are discovered by
napari through the npe2 manifest ``napari_pfsdm/napari.yaml``; import them from their modules
(``napari_pfsdm.napari._widget.AnalysisWidget``, ``._plots.TrajectoryPlotWidget``,
``._plots.ShapeComparisonWidget``).
"""
