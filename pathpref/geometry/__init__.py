"""Geometry: maps and the structures the paper's method is built on.

* :mod:`.maps` (``MapSpec``, ``load_map``): H-polytope obstacles, cells, goal band, ``t_max``;
* :mod:`.arrangement` (``Arrangement``) and :mod:`.coarse`: the decomposition of free space
  into convex polytopes; :mod:`.polygon`: clipping and H/V conversions;
* :mod:`.graph` (``PolytopeGraph``): adjacency of polytopes, neighbour tables;
* :mod:`.grid` (``GridMotion``, ``STAY``): the eight moves, costs and blocked moves (SPEC 3);
* :mod:`.preference`: the map's preferred transitions; :mod:`.following`: paths that obey
  them; :mod:`.world` (``World``, ``load_world``): all of the above for one map;
* :mod:`.generate`: random floor plans with rotated obstacles.
"""
