"""The napari plugin: the analysis, plots and prediction docks, picture layers, sample data.

The only part of napari-pfsdm that imports Qt, napari or magicgui (the model, ``_model``, and the
results, ``_results``, import neither). napari discovers the docks through the npe2 manifest
``napari_pfsdm/napari.yaml``.
"""
