"""pathpref: infer where a person wants a robot to go, and by which path, from sparse nudges.

An implementation of Peltzer et al., "Incorporating Human Path Preferences in Robot Navigation
with Minimal Interventions" (arXiv 2303.03530), from the grid world to MuJoCo.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("pathpref")
except PackageNotFoundError:  # running from a source tree that was never installed
    __version__ = "0+unknown"
