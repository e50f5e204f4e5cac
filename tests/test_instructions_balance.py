"""Balancing high-level types across a scene: exact quotas where the goals allow, optimal shortfall, seeded."""

from __future__ import annotations

import itertools
from collections import Counter

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from profiles import examples

from sagebench.instructions.balance import balance_types, quotas

FIVE = ("A", "B", "C", "D", "E")
EQUAL = {t: 1.0 for t in FIVE}


def test_quotas_split_by_largest_remainder_and_ties_go_by_order():
    assert quotas(200, EQUAL, FIVE) == {t: 40 for t in FIVE}
    assert quotas(7, {"A": 1, "B": 1, "C": 1}, ["C", "A", "B"]) == {"C": 3, "A": 2, "B": 2}
    assert quotas(10, {"A": 2, "B": 1, "C": 1}, ["C", "B", "A"]) == {"C": 3, "B": 2, "A": 5}
    assert quotas(3, {"A": 0.1, "B": 0.2}, ["A", "B"]) == {"A": 1, "B": 2}  # exact rationals: 1 and 2, no drift


def test_every_type_gets_its_quota_when_every_goal_allows_it():
    for n, seed in ((200, 0), (203, 1), (7, 2)):
        balance = balance_types([set(FIVE)] * n, EQUAL, np.random.default_rng(seed))
        counts = Counter(balance.chosen)
        assert sorted(counts.values()) == sorted([n // 5 + 1] * (n % 5) + [n // 5] * (5 - n % 5))
        assert dict(counts) == dict(balance.quota) and balance.short() == {}


def test_shares_are_followed_and_zero_shares_never_chosen():
    balance = balance_types([set(FIVE)] * 100, {"A": 2, "B": 1, "C": 1, "D": 0}, np.random.default_rng(0))
    assert Counter(balance.chosen) == {"A": 50, "B": 25, "C": 25}


def test_a_type_few_goals_allow_falls_short_and_says_why():
    options = [set(FIVE) if i < 10 else set(FIVE) - {"E"} for i in range(200)]
    balance = balance_types(options, EQUAL, np.random.default_rng(0))
    counts = Counter(balance.chosen)
    assert counts["E"] == 10 and sorted(counts[t] for t in "ABCD") == [47, 47, 48, 48]  # the other 190, shared
    assert balance.short() == {"E": 10}
    assert balance.summary() == ("A 47/40, B 47/40, C 48/40, D 48/40, E 10/40 (it describes only 10 of the 200 "
                                 "goals) (chosen/quota)")


def test_a_type_whose_goals_other_types_need_falls_short_and_says_why():
    # B and C can each describe only the third goal: whichever gets it, the other has none
    balance = balance_types([{"A"}, {"A"}, {"B", "C"}], {"A": 1, "B": 1, "C": 1}, np.random.default_rng(0))
    (short,) = balance.short()
    assert balance.chosen[:2] == ("A", "A") and balance.short() == {short: 0} and short in "BC"
    assert f"{short} 0/1 (it describes 1 of the 3 goals, 1 of them needed by other types' quotas)" in balance.summary()


def test_a_goal_only_one_type_describes_gets_that_type_first():
    # greedy in order would give the first trajectory A and leave the second with nothing under quota
    for seed in range(5):
        assert balance_types([{"A", "B"}, {"A"}], {"A": 1, "B": 1}, np.random.default_rng(seed)).chosen == ("B", "A")


def test_a_goal_no_type_describes_gets_none_and_is_counted():
    balance = balance_types([set(), {"A"}, {"B"}], {"A": 1, "B": 0}, np.random.default_rng(0))
    assert balance.chosen == (None, "A", None)
    assert balance.summary() == "A 1/1 (chosen/quota); 2 trajectories without one: no type describes their goal"


def test_same_seed_same_choice_other_seed_other_trajectories():
    a = balance_types([set(FIVE)] * 50, EQUAL, np.random.default_rng(3))
    assert a == balance_types([set(FIVE)] * 50, EQUAL, np.random.default_rng(3))
    assert a.chosen != balance_types([set(FIVE)] * 50, EQUAL, np.random.default_rng(4)).chosen


@settings(max_examples=examples(150))
@given(st.lists(st.sets(st.sampled_from("ABC")), min_size=1, max_size=6),
       st.fixed_dictionaries({t: st.integers(0, 3) for t in "ABC"}).filter(lambda s: any(s.values())),
       st.integers(0, 2**32 - 1))
def test_the_shortfall_is_the_least_any_assignment_has(options, shares, seed):
    """Brute force over every assignment: none misses the quotas by fewer trajectories than the balance does."""
    balance = balance_types(options, shares, np.random.default_rng(seed))
    live = [sorted(t for t in o if shares[t] > 0) for o in options]
    for o, c in zip(live, balance.chosen, strict=True):
        assert (c is None) if not o else (c in o)

    def shortfall(counts) -> int:
        return sum(max(0, q - counts[t]) for t, q in balance.quota.items())

    best = min(shortfall(Counter(c)) for c in itertools.product(*[o for o in live if o]))
    assert shortfall(Counter(balance.chosen)) == best
