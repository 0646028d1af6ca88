"""The paper's reported numbers (Peltzer et al. 2023), the one place they are typed in:
reports print them next to ours, benchmarks compare against them."""

#: Table I: success rate per method and Delta_T (Map 1 = ``simple``, gamma_h = 1.5, T_max = 30).
TABLE_I = {
    "compliant": {1: 0.67, 5: 0.33, 10: 0.33, 20: 0.17, 30: 0.17},
    "goal_only": {1: 0.28, 5: 0.18, 10: 0.17, 20: 0.17, 30: 0.16},
    "path_preference": {1: 0.55, 5: 0.42, 10: 0.41, 20: 0.34, 30: 0.30},
    "blended": {1: 0.55, 5: 0.39, 10: 0.44, 20: 0.44, 30: 0.34},
}

#: Table II, ms: (solve goal only, solve path preference, update goal only, update path pref).
TABLE_II = {
    "simple": (449.0, 510.0, 0.6, 73.5),
    "office": (2984.0, 2847.0, 0.7, 28.7),
    "classroom": (2305.0, 2063.0, 0.4, 38.3),
}


def update_ms(map_name: str) -> float | None:
    """Table II's path-preference belief update time on ``map_name`` (None: not in the paper)."""
    row = TABLE_II.get(map_name)
    return None if row is None else row[3]


def solve_ms(map_name: str) -> float | None:
    """Table II's path-preference solve time on ``map_name`` (None: not in the paper)."""
    row = TABLE_II.get(map_name)
    return None if row is None else row[1]
