"""Edge guards: reduced ordered binary decision diagrams over atomic-proposition indices.

A guard is a Boolean function of the atomic propositions (AP ``i`` is variable ``i``, ordered
by index). :class:`Bdd` wraps a node of one process-wide, hash-consed node table, so two guards
are equal exactly when they are the same Boolean function (canonicity) — the translator relies
on this to merge edges and states. Nodes are never freed; a mission planner creates a few
thousand at most.

Valuations are ``int`` bit masks: bit ``i`` set means AP ``i`` holds.

Printing uses the irredundant sum-of-products of Minato-Morreale (ISOP), so a guard prints as a
short DNF, e.g. ``a & !b | c``.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

__all__ = ["Bdd", "cube", "from_minterms", "valuation_mask"]

_TERMINAL_VAR = 1 << 30
# Node table: node 0 is false, node 1 is true.
_var: list[int] = [_TERMINAL_VAR, _TERMINAL_VAR]
_lo: list[int] = [0, 1]
_hi: list[int] = [0, 1]
_unique: dict[tuple[int, int, int], int] = {}
_and_cache: dict[tuple[int, int], int] = {}
_or_cache: dict[tuple[int, int], int] = {}
_not_cache: dict[int, int] = {0: 1, 1: 0}
_isop_cache: dict[tuple[int, int], tuple[int, tuple[tuple[tuple[int, bool], ...], ...]]] = {}


def _mk(v: int, lo: int, hi: int) -> int:
    if lo == hi:
        return lo
    key = (v, lo, hi)
    n = _unique.get(key)
    if n is None:
        n = len(_var)
        _var.append(v)
        _lo.append(lo)
        _hi.append(hi)
        _unique[key] = n
    return n


def _not(u: int) -> int:
    r = _not_cache.get(u)
    if r is None:
        r = _mk(_var[u], _not(_lo[u]), _not(_hi[u]))
        _not_cache[u] = r
    return r


def _and(u: int, v: int) -> int:
    if u == 0 or v == 0:
        return 0
    if u == 1:
        return v
    if v == 1 or u == v:
        return u
    if u > v:
        u, v = v, u
    key = (u, v)
    r = _and_cache.get(key)
    if r is None:
        vu, vv = _var[u], _var[v]
        m = min(vu, vv)
        u0, u1 = (_lo[u], _hi[u]) if vu == m else (u, u)
        v0, v1 = (_lo[v], _hi[v]) if vv == m else (v, v)
        r = _mk(m, _and(u0, v0), _and(u1, v1))
        _and_cache[key] = r
    return r


def _or(u: int, v: int) -> int:
    if u == 1 or v == 1:
        return 1
    if u == 0:
        return v
    if v == 0 or u == v:
        return u
    if u > v:
        u, v = v, u
    key = (u, v)
    r = _or_cache.get(key)
    if r is None:
        vu, vv = _var[u], _var[v]
        m = min(vu, vv)
        u0, u1 = (_lo[u], _hi[u]) if vu == m else (u, u)
        v0, v1 = (_lo[v], _hi[v]) if vv == m else (v, v)
        r = _mk(m, _or(u0, v0), _or(u1, v1))
        _or_cache[key] = r
    return r


def _isop(lo: int, up: int):
    """Minato-Morreale irredundant SOP of some f with ``lo <= f <= up``: ``(node, cubes)``."""
    if lo == 0:
        return 0, ()
    if up == 1:
        return 1, ((),)
    key = (lo, up)
    hit = _isop_cache.get(key)
    if hit is not None:
        return hit
    v = min(_var[lo], _var[up])
    l0, l1 = (_lo[lo], _hi[lo]) if _var[lo] == v else (lo, lo)
    u0, u1 = (_lo[up], _hi[up]) if _var[up] == v else (up, up)
    # cubes with !v, cubes with v, cubes without v
    n0, c0 = _isop(_and(l0, _not(u1)), u0)
    n1, c1 = _isop(_and(l1, _not(u0)), u1)
    lstar = _or(_and(l0, _not(n0)), _and(l1, _not(n1)))
    nstar, cstar = _isop(lstar, _and(u0, u1))
    node = _or(_or(_and(_mk(v, 1, 0), n0), _and(_mk(v, 0, 1), n1)), nstar)
    cubes = (
        tuple(((v, False),) + c for c in c0)
        + tuple(((v, True),) + c for c in c1)
        + cstar
    )
    _isop_cache[key] = (node, cubes)
    return node, cubes


class Bdd:
    """A guard: a Boolean function of AP indices (canonical; ``==`` is logical equivalence).

    Build guards with :meth:`Bdd.var`, :data:`Bdd.true`, :data:`Bdd.false`, :func:`cube` and
    the operators ``&``, ``|``, ``~``.

    Examples
    --------
    >>> g = Bdd.var(0) & ~Bdd.var(1)
    >>> g.holds(0b01), g.holds(0b11)
    (True, False)
    >>> g.to_str(["a", "b"])
    'a & !b'
    """

    __slots__ = ("node",)
    true: "Bdd"
    false: "Bdd"

    def __init__(self, node: int):
        self.node = node

    @staticmethod
    def var(i: int) -> "Bdd":
        """The guard "AP ``i`` holds"."""
        if i < 0:
            raise ValueError(f"AP index must be >= 0, got {i}")
        return Bdd(_mk(int(i), 0, 1))

    def __and__(self, other: "Bdd") -> "Bdd":
        return Bdd(_and(self.node, other.node))

    def __or__(self, other: "Bdd") -> "Bdd":
        return Bdd(_or(self.node, other.node))

    def __invert__(self) -> "Bdd":
        return Bdd(_not(self.node))

    def __eq__(self, other) -> bool:
        return isinstance(other, Bdd) and other.node == self.node

    def __hash__(self) -> int:
        return hash(self.node)

    def __bool__(self) -> bool:
        raise TypeError("a guard has no truth value; use .is_false / .is_true / .holds(mask)")

    @property
    def is_false(self) -> bool:
        return self.node == 0

    @property
    def is_true(self) -> bool:
        return self.node == 1

    def implies(self, other: "Bdd") -> bool:
        """True when every valuation satisfying ``self`` satisfies ``other``."""
        return _and(self.node, _not(other.node)) == 0

    def intersects(self, other: "Bdd") -> bool:
        return _and(self.node, other.node) != 0

    def holds(self, mask: int) -> bool:
        """Evaluate at the valuation ``mask`` (bit ``i`` = AP ``i``)."""
        u = self.node
        var, lo, hi = _var, _lo, _hi
        while u > 1:
            u = hi[u] if (mask >> var[u]) & 1 else lo[u]
        return u == 1

    def support(self) -> frozenset[int]:
        """Indices of the APs the guard depends on."""
        seen: set[int] = set()
        out: set[int] = set()
        stack = [self.node]
        while stack:
            u = stack.pop()
            if u <= 1 or u in seen:
                continue
            seen.add(u)
            out.add(_var[u])
            stack.append(_lo[u])
            stack.append(_hi[u])
        return frozenset(out)

    def cubes(self) -> tuple[tuple[tuple[int, bool], ...], ...]:
        """Irredundant sum of products: each cube is ``((ap_index, polarity), ...)``."""
        return _isop(self.node, self.node)[1]

    def to_str(self, names: Sequence[str] | None = None, *, and_: str = " & ", or_: str = " | ",
               not_: str = "!", true: str = "true", false: str = "false") -> str:
        """DNF text; ``names[i]`` prints AP ``i`` (default: the index, as HOA does)."""
        if self.node == 0:
            return false
        if self.node == 1:
            return true
        parts = []
        for c in self.cubes():
            lits = [("" if pol else not_) + (names[i] if names is not None else str(i))
                    for i, pol in c]
            parts.append(and_.join(lits) if lits else true)
        return or_.join(parts)

    def __repr__(self) -> str:
        return f"Bdd<{self.to_str()}>"

    def __reduce__(self):
        return (_from_cubes, (self.cubes(),))


def _from_cubes(cubes) -> Bdd:
    g = Bdd.false
    for c in cubes:
        g = g | cube(c)
    return g


def cube(literals: Iterable[tuple[int, bool]]) -> Bdd:
    """Conjunction of literals ``(ap_index, polarity)``."""
    node = 1
    for i, pol in sorted(literals, reverse=True):
        lit = _mk(int(i), 0, 1) if pol else _mk(int(i), 1, 0)
        node = _and(node, lit)
    return Bdd(node)


def valuation_mask(true_aps: Iterable[str], aps: Sequence[str]) -> int:
    """Bit mask of the valuation where exactly ``true_aps`` hold (names not in ``aps`` ignored)."""
    index = {a: i for i, a in enumerate(aps)}
    m = 0
    for a in true_aps:
        i = index.get(a)
        if i is not None:
            m |= 1 << i
    return m


Bdd.true = Bdd(1)
Bdd.false = Bdd(0)


def from_minterms(letters: Iterable[int], nvars: int) -> Bdd:
    """The guard true exactly at the valuations ``letters`` (masks over ``nvars`` APs).

    Built by Shannon expansion over the letters themselves (variable 0 on top): a branch with
    no letter is ``false``, one with every valuation of its remaining variables ``true``, so
    it costs ``O(len(letters) * nvars)`` (a few letters over many APs, as the exclusive
    alphabets of :func:`tamp.ltl.to_buchi`, stay cheap).
    """
    size = 1 << nvars
    ms = set()
    for m in letters:
        if not 0 <= m < size:
            raise ValueError(f"letter {m} is not a valuation of {nvars} APs")
        ms.add(m)

    def build(sub: list[int], var: int) -> int:
        if not sub:
            return 0
        if len(sub) == 1 << (nvars - var):
            return 1  # (distinct letters) every valuation of variables var..nvars-1
        bit = 1 << var
        lo = build([m for m in sub if not m & bit], var + 1)
        hi = build([m for m in sub if m & bit], var + 1)
        return _mk(var, lo, hi)

    return Bdd(build(list(ms), 0))
