"""Simulation versus recordings (METHODS section 6), built as a library of physics terms:

- ``recordings``: program and recording CSVs, the Michigan adapter, alignment;
- ``simulator``: the program's knots and the simulator (the machine model
  camsmooth.machine.model.ErrorModel, its one real pose and one first-order integrator);
- ``problem``: noise floors, outliers, located intervals, ``Options`` and the frozen ``Problem``;
- ``terms``: one module per physics term, one interface (``terms.base.Term``);
- ``selector``: fitting (camsmooth.machine.fitting), held-out scoring and the rule that names a
  term only when it is physics the user can act on;
- ``findings``: ``diagnose``, ``validate`` and the typed findings (FINDINGS.json);
- ``model_io``: the model JSON; ``engine``: the public names gathered in one place.
- ``iso230``: ISO 230-2 figures of a bidirectional positioning run and the LinuxCNC pitch-error
  compensation table (``camsmooth iso230``).
"""
