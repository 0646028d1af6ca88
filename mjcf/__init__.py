"""Hand-written MJCF models (``navigate.xml``, ``carry_tool.xml``) and the Stanford TidyBot
vendored from MuJoCo Menagerie (``stanford_tidybot/``, its own LICENSE and README), shipped as
``pathpref.mjcf``.

The folder stays at the top of the repository (the project's layout); ``pyproject.toml`` maps it
to the package ``pathpref.mjcf`` so that a wheel carries the XML files.
"""
