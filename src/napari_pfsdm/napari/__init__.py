"""The napari plugin: the analysis, plots, prediction and study docks, picture layers, sample
data.

The only part of napari-pfsdm that imports Qt, napari or magicgui (the models, ``_model`` and
``_study_model``, and the results, ``_results``, import neither). napari discovers the docks
through the npe2 manifest ``napari_pfsdm/napari.yaml``.
"""
