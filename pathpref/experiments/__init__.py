"""Experiments: many episodes, stored and reported.

* :mod:`.sweep` (``sweep_specs``, ``run_sweep``, ``fixed_specs``): grids of episodes with
  common random numbers, resumable; :mod:`.backends`: local process pool or Ray;
* :mod:`.store` (``ResultStore``, ``row_spec``): the SQLite results store;
  :mod:`.migrate`: schema upgrades;
* :mod:`.report` (``load_records``, ``markdown_tables``, ``wilson``): tables with intervals;
  :mod:`.curves`: Fig. 4's belief curves; :mod:`.timing`: Table II;
  :mod:`.paper`: the paper's reported numbers.
"""
