"""pathpref's examples (the tutorial, a PPO training run, example maps and demo files),
shipped in the wheel as the data package ``pathpref.examples``; ``pathpref examples DEST``
copies them out (:mod:`pathpref.apps.examples`). Run them from the copy, not from here."""
