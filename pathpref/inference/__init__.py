"""Inference: the Boltzmann human and the robot's belief.

* :mod:`.costs` (``build_cost_tables``): constrained shortest-path costs per goal and exit;
* :mod:`.human` (``ObservationModel``, ``SimulatedHuman``): ``P(heading | s, g, p_v)`` (SPEC 4);
* :mod:`.belief` (``Belief``, ``PreferenceBelief``, ``GoalBelief``): the exact posterior over
  goal and preference (paper Eq. 2, SPEC 5) and the goal-only one;
* :mod:`.rationality` (``GammaBelief``): the human's rationality ``gamma`` inferred too, exact
  over a grid of values (a mixture of one belief per ``gamma``, weighted by its evidence).
"""
