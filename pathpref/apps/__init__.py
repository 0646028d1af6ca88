"""Applications, the top of the house: the ``pathpref`` command line (:mod:`.cli`), the demo
(:mod:`.demo`), rendered rollouts (:mod:`.rollout`), the interactive viewer
(:mod:`.interact`) and the benchmarks (:mod:`.benchmarks`). They may use every layer below."""
