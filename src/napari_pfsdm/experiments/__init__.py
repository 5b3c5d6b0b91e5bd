"""Reproductions of the paper's experiments and the demo's reports.

Unlike the library, these modules print and write files (CSV tables, PNG figures). They are
never imported by the library's ``core``, ``analysis``, ``batch`` or ``napari`` code; only the
command line (``pfsdm demo``), the scripts in ``benchmarks/`` and the tests use them.

- :mod:`.synthetic_five_shapes`: the synthetic five-shape benchmark, PF-SDM against EFA and GPA;
- :mod:`.gastruloid_report`: the gastruloid axis-number prediction, end to end;
- :mod:`.pixel_baseline`: the pixel-space baselines (scikit-learn, optional torch CNN) it
  compares with.

Headless: never imports Qt or napari.
"""
