"""Visualisation at the edge, fed by plain data: map figures (:mod:`.mapdraw`), episode and
result figures (:mod:`.episodes`, :mod:`.plots`), rerun recordings (:mod:`.rerun_log`)."""
