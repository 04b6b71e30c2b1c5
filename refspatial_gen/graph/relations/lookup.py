"""Cell and table rules shared by relations of one storage kind (see base.py for the kinds).

A relation module picks the rules of its storage kind when it registers (`cell=pair_cell("left")`, ...);
graph/tables.py applies them. Each table rule builds exactly what its cell rule answers one instance at a
time (tests/test_graph_tables.py compares every cell of every table).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from refspatial_gen.graph.constants import Thresholds
from refspatial_gen.graph.relations.base import T_FALSE, T_MISSING, T_UNDECIDED, Cell, CellRule, Rows

if TYPE_CHECKING:
    from refspatial_gen.graph.tables import RelationTables

_INF = float("inf")
_PAIR_CODES = {True: (1, 0), False: (0, 1), None: (2, 2)}  # stored holds -> codes of (a, b) and (b, a)
Margin = Callable[[Thresholds], float]


def stored_cell(rid: str) -> CellRule:
    """The stored instance, else not evaluated (unary quantities)."""

    def cell(t: RelationTables, args: tuple[Any, ...]) -> Cell | None:
        f = t.stored(rid, args)
        return None if f is None else Cell(f.holds, float(f.value), f.margin)

    return cell


def pair_cell(rid: str) -> CellRule:
    """Antisymmetric, stored once per pair: the reversed pair is the negation, with the value negated."""

    def cell(t: RelationTables, args: tuple[Any, ...]) -> Cell | None:
        f = t.stored(rid, args)
        if f is not None:
            return Cell(f.holds, float(f.value), f.margin)
        f = t.stored(rid, args[::-1])
        if f is None:
            return None
        return Cell(None if f.holds is None else not f.holds, -float(f.value), f.margin)

    return cell


def pair_table(rid: str) -> Callable[[RelationTables], Rows]:
    def table(t: RelationTables) -> Rows:
        pos = t.pos
        n = len(t.ids)
        codes = [[T_MISSING] * n for _ in range(n)]
        for f in t.facts_of(rid):
            args = f.args
            if len(args) == 2:
                i, j = pos.get(args[0]), pos.get(args[1])
                if i is not None and j is not None and i != j:
                    codes[i][j], codes[j][i] = _PAIR_CODES[f.holds]
        return codes

    return table


def symmetric_cell(rid: str, absent: Margin | None) -> CellRule:
    """Stored once per pair, either way round. Absent: False (value = the pair's distance, margin `absent`)
    when the pair has a stored distance, else not evaluated; with `absent` None, never False."""

    def cell(t: RelationTables, args: tuple[Any, ...]) -> Cell | None:
        f = t.stored(rid, args) or t.stored(rid, args[::-1])
        if f is not None:
            return Cell(f.holds, float(f.value), f.margin)
        if absent is None or t.th is None:
            return None
        d = t.distance(*args)
        return None if d is None else Cell(False, d, absent(t.th))

    return cell


def _overlay(t: RelationTables, rid: str, out: Rows, symmetric: bool) -> Rows:
    """Write the stored instances of `rid` over a table of absent-instance codes."""
    pos = t.pos
    direct = []
    for f in t.facts_of(rid):
        if len(f.args) == 2:
            a, b = f.args
            if a in pos and b in pos and a != b:
                h = f.holds
                direct.append((pos[a], pos[b], T_UNDECIDED if h is None else int(bool(h))))
    if symmetric:  # a reversed stored instance counts unless the pair is stored as asked
        for i, j, c in direct:
            out[j][i] = c
    for i, j, c in direct:
        out[i][j] = c
    return out


def symmetric_table(rid: str) -> Callable[[RelationTables], Rows]:
    def table(t: RelationTables) -> Rows:
        out = [[T_MISSING if d == _INF else T_FALSE for d in row] for row in t.distance_rows()]
        return _overlay(t, rid, out, True)

    return table


def sparse_cell(rid: str, absent: Callable[[RelationTables, tuple[Any, ...]], Cell | None]) -> CellRule:
    """Only holding and undecided instances stored (as asked); an absent one follows `absent`."""

    def cell(t: RelationTables, args: tuple[Any, ...]) -> Cell | None:
        f = t.stored(rid, args)
        if f is not None:
            return Cell(f.holds, float(f.value), f.margin)
        return absent(t, args)

    return cell


def false_absent(margin: Margin) -> Callable[[RelationTables, tuple[Any, ...]], Cell | None]:
    def absent(t: RelationTables, args: tuple[Any, ...]) -> Cell | None:
        return None if t.th is None else Cell(False, 0.0, margin(t.th))

    return absent


def sparse_table(
    rid: str, absent_row: Callable[[RelationTables, int], int] | None = None
) -> Callable[[RelationTables], Rows]:
    """Absent instances False (or `absent_row(t, object id)` for the whole row of that first argument)."""

    def table(t: RelationTables) -> Rows:
        n = len(t.ids)
        if absent_row is None:
            out = [[T_FALSE] * n for _ in range(n)]
        else:
            out = [[absent_row(t, i)] * n for i in t.ids]
        return _overlay(t, rid, out, False)

    return table
