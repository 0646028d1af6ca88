"""Planning: the POMDP and the methods.

* :mod:`.pomdp` (``Rewards``, ``Preset``, ``get_preset``, ``transition_reward``): rewards,
  presets (``paper``, ``original``, ``robust``) and the reward rule of SPEC 6;
* :mod:`.pomcp` (``POMCP``): the paper's PO-UCT search, compiled; :mod:`.guided`: the robust
  search; :mod:`.tree`: the tree arrays both share;
* :mod:`.policies` (``Policy``, ``make_policy``, ``register_method``, ``METHODS``): the four
  methods of the paper and the reference methods ``oracle`` and ``goal_known``.
"""
