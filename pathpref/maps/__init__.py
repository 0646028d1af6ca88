"""The built-in maps as JSON files (``simple``, ``office``, ``classroom``: the paper's three,
with the authors' numbering; see ``geometry/maps.py`` for the format)."""
