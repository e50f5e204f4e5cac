"""Which high-level type each of a scene's trajectories gets: the configured mix as exact quotas, where goals allow.

A trajectory can take only the types that can describe its goal (`high_level.sentences`). The quotas are
the configured shares of the trajectories (largest remainder; equal remainders ordered by the seed). A
maximum flow from trajectories to types, each type's capacity its quota, assigns as many trajectories as
the quotas allow. While some are left over, the types they cannot reach keep what they have (a type
with too few goals it can describe stays short of its quota), and the trajectories not held by those
are shared again by the configured shares among the rest, so every trajectory that some type can
describe gets one, and the counts are the quotas wherever the goals allow them.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass
from fractions import Fraction

import numpy as np
from scipy.sparse import csr_array
from scipy.sparse.csgraph import breadth_first_order, maximum_flow


@dataclass(frozen=True)
class TypeBalance:
    """The types chosen for a scene's trajectories and how they compare with the configured mix."""

    chosen: tuple[str | None, ...]  # per trajectory; None when no type with a positive share can describe its goal
    quota: Mapping[str, int]  # type -> its share of the describable trajectories
    describable: Mapping[str, int]  # type -> trajectories whose goal it can describe

    def count(self, kind: str) -> int:
        return sum(c == kind for c in self.chosen)

    def short(self) -> dict[str, int]:
        """Types below their quota -> their count."""
        return {t: self.count(t) for t, q in self.quota.items() if self.count(t) < q}

    def summary(self) -> str:
        """Each type's count against its quota, why a type fell short, and the trajectories no type describes."""
        n = sum(c is not None for c in self.chosen)
        parts = []
        for t, q in self.quota.items():
            got, can = self.count(t), self.describable[t]
            why = "" if got >= q else (
                f" (it describes only {can} of the {n} goals)" if can < q else
                f" (it describes {can} of the {n} goals, {can - got} of them needed by other types' quotas)")
            parts.append(f"{t} {got}/{q}{why}")
        none = len(self.chosen) - n
        return ", ".join(parts) + " (chosen/quota)" + (
            f"; {none} trajectories without one: no type describes their goal" if none else "")


def quotas(n: int, shares: Mapping[str, float], order: Sequence[str]) -> dict[str, int]:
    """`n` split by `shares` (largest remainder, exact rationals); equal remainders go first to types early in `order`."""
    total = sum(Fraction(shares[t]) for t in order)
    exact = {t: n * Fraction(shares[t]) / total for t in order}
    out = {t: int(exact[t]) for t in order}
    by_remainder = sorted(order, key=lambda t: -(exact[t] - out[t]))  # stable: `order` breaks ties
    for t in by_remainder[:n - sum(out.values())]:
        out[t] += 1
    return out


def balance_types(options: Sequence[Collection[str]], shares: Mapping[str, float],
                  rng: np.random.Generator) -> TypeBalance:
    """One type per trajectory among its `options` (the types that can describe its goal), counts as close to
    `shares` (type -> relative share; zero shares never chosen) as the options allow; seeded by `rng`."""
    kinds = [t for t in shares if shares[t] > 0]
    kinds = [kinds[i] for i in rng.permutation(len(kinds))]  # who gets an odd one, and the flow's edge order
    opts = [[t for t in kinds if t in o] for o in options]
    pool = [i for i, o in enumerate(opts) if o]
    pool = [pool[i] for i in rng.permutation(len(pool))]  # which trajectories a type's quota reaches first
    first = quotas(len(pool), shares, kinds)
    cap, chosen = dict(first), {}
    while True:
        flow, reached = _assign(opts, pool, kinds, cap)
        if len(flow) == len(pool):
            chosen.update(flow)
            break
        # a type no left-over trajectory can reach keeps what it has; the rest are shared again among the others
        chosen.update({i: t for i, t in flow.items() if t not in reached})
        pool = [i for i in pool if i not in chosen]
        kinds = [t for t in kinds if t in reached]
        more = quotas(len(pool), shares, kinds)
        cap = {t: max(cap[t], more[t]) for t in kinds}
    in_order = [t for t in shares if t in first]  # reported in the caller's order, not the seeded one
    return TypeBalance(tuple(chosen.get(i) for i in range(len(opts))), {t: first[t] for t in in_order},
                       {t: sum(t in o for o in opts) for t in in_order})


def _assign(opts: list[list[str]], pool: list[int], kinds: list[str],
            cap: Mapping[str, int]) -> tuple[dict[int, str], set[str]]:
    """A maximum assignment of the trajectories `pool` to `kinds` within `cap` (trajectory -> type), and the
    types a trajectory left over can still reach by moving others (reachable in the residual graph)."""
    n, k = len(pool), len(kinds)
    source, sink = 0, n + k + 1
    node = {t: n + 1 + j for j, t in enumerate(kinds)}
    rows, cols = [], []
    for r, i in enumerate(pool, start=1):
        mine = [node[t] for t in opts[i] if t in node]
        rows += [source, *[r] * len(mine)]
        cols += [r, *mine]
    caps = [1] * len(rows) + [cap[t] for t in kinds]
    rows += [node[t] for t in kinds]
    cols += [sink] * k
    graph = csr_array((np.array(caps, np.int32), (np.array(rows), np.array(cols))), shape=(sink + 1, sink + 1))
    result = maximum_flow(graph, source, sink)
    flow = result.flow.tocoo()
    out = {pool[r - 1]: kinds[c - n - 1] for r, c, f in zip(flow.row, flow.col, flow.data)
           if f > 0 and 1 <= r <= n and n < c < sink}
    residual = csr_array((graph - result.flow) > 0).astype(np.int8)
    reached = set(breadth_first_order(residual, source, return_predecessors=False).tolist())
    return out, {t for t in kinds if node[t] in reached}
