"""Force-interaction studies with people (``pathpref study``): study files, trials in MuJoCo
physics driven by a person's pushes (browser, viewer or script), recorded as they happen in the
results store. Above ``experiments`` (it records there), ``sim`` and ``viz`` (physics and rerun
recordings); below ``apps``."""
