"""Columnar (struct-of-arrays) storage behind the hot components, owned by each World.

esper keeps one Python object per component; hot systems want whole numpy
columns. A :class:`Columnar` component is both: an ordinary object that esper
stores and user code reads and writes per entity (``vel.linear = (2, 0, 0)``),
whose values live in one row of a :class:`Table` — one table per component
class *per World*, one growable numpy array per field.

The lifecycle is explicit, never left to the garbage collector:

* A component made outside a world (``Velocity((1, 0, 0))``, or a block from
  :meth:`Columnar.bulk`) keeps its values in a small private table of its own.
* When its entity is in a World, the World copies the values into its own
  table and the component points at that row (:meth:`Table.attach`). Bulk
  blocks move in one array copy, into free rows first.
* When the component is removed or its entity deleted — through the World or
  through esper's own functions, which the World reconciles before every
  system runs and before every column read — its values are copied back into
  a private table and its row is freed for reuse (:meth:`Table.detach`).

So a component object is always a valid value and never aliases another
entity's row: there are no stale handles to detect. Reading a vector field
returns a *read-only copy* (``vel.linear[0] = 2`` raises; write the whole field),
for the same reason: a kept view could otherwise outlive its row. Copy,
deepcopy and pickle give an independent value; components compare by value
and, being mutable, are unhashable.

Vectorised code reads and writes whole columns through
:meth:`driftframe.framework.world.World.columns` (gather/scatter in a stated
entity order) or, inside systems, through :class:`Query` rows into
:attr:`Table.data`.
"""
from __future__ import annotations

from operator import attrgetter, itemgetter
from typing import TYPE_CHECKING, Any

import esper
import numpy as np

from driftframe.framework import access_check, validate

if TYPE_CHECKING:
    from typing import Self

    from numpy.typing import ArrayLike


class Field:
    """A typed column on a :class:`Columnar` component.

    ``shape`` is the per-entity shape (``()`` for a scalar), ``doc`` states
    the unit and frame. ``allow_inf`` admits +-inf (infinite mass), ``check``
    is an optional extra validator ``(name, array) -> array``.
    """

    def __init__(self, shape=(), doc: str = "", *, default=0.0, allow_inf: bool = False,
                 dtype=np.float64, check=None):
        self.shape = tuple(shape)
        self.doc = doc
        # a scalar default for a vector field fills it (0.0 -> zeros(3))
        self.default = np.full(self.shape, default, dtype) if self.shape and np.ndim(default) == 0 else default
        self.allow_inf = allow_inf
        self.dtype = np.dtype(dtype)
        self.check = check
        self.name = ""
        self.owner = ""

    def __set_name__(self, owner, name):
        self.name = name
        self.owner = owner.__name__
        self.__doc__ = self.doc

    def __get__(self, obj, objtype=None):
        if obj is None:
            return self
        value = obj._table.data[self.name][obj._row]
        if self.shape:
            value = value.copy()
            value.flags.writeable = False
            return value
        return value.item()

    def coerce(self, value) -> np.ndarray:
        """Validate one entity's value for this field."""
        label = f"{self.owner}.{self.name}"
        if self.dtype.kind == "f":
            if self.shape:
                arr = validate.vector(label, value, self.shape, allow_inf=self.allow_inf)
            else:
                arr = np.float64(validate.scalar(label, value, allow_inf=self.allow_inf))
        else:
            arr = np.asarray(value, dtype=self.dtype)
            if arr.shape != self.shape:
                raise ValueError(f"{label} must have shape {self.shape}, got {arr.shape}")
        if self.check is not None:
            arr = self.check(label, arr)
        return arr

    def coerce_column(self, label: str, value, n: int) -> np.ndarray:
        """Validate a whole column of ``n`` values, shape ``(n, *shape)`` (the error names the first bad row)."""
        arr = np.asarray(value)
        if self.dtype.kind == "f":
            arr = validate.array(label, arr, self.shape, n, allow_inf=self.allow_inf)
        elif arr.shape != (n, *self.shape):
            raise ValueError(f"{label} must have shape {(n, *self.shape)}, got {arr.shape}")
        if self.check is not None:
            arr = self.check(label, arr)
        return arr

    def __set__(self, obj, value):
        obj._table.data[self.name][obj._row] = self.coerce(value)


class Table:
    """One growable array per field of one component class, with its rows' owners.

    ``world`` is the owning world's name (None for a component's private
    table). ``owner[row]`` is the component object living in ``row`` (None
    when free) and ``entity[row]`` its entity id (-1 when free). Free rows are
    reused lowest first, so bulk blocks stay contiguous when they can.
    """

    def __init__(self, cls, capacity: int = 16, world: str | None = None):
        self.cls = cls
        self.fields: dict[str, Field] = cls._fields
        self.world = world
        self.capacity = max(1, int(capacity))
        self.size = 0                                   # high-water mark of rows ever used
        self.free: list[int] = []                       # freed rows below size
        self.data = {n: np.zeros((self.capacity, *f.shape), f.dtype) for n, f in self.fields.items()}
        self.owner: list = [None] * self.capacity
        self.entity = np.full(self.capacity, -1, np.int64)
        #: Bumped whenever a row is attached or detached (for caches keyed on membership).
        self.version = 0
        #: ``born[row]``: the version at which the row's component was attached (-1: never), so a step that
        #: began at version v can tell the rows taken since (``born > v``) from its own (framework/step.py).
        self.born = np.full(self.capacity, -1, np.int64)
        self._by_entity = None

    def __repr__(self):
        return f"<Table {self.cls.__name__} of {self.world or 'a component'}: {self.live} live rows>"

    @property
    def live(self) -> int:
        """Rows in use."""
        return self.size - len(self.free)

    def _grow(self, need: int) -> None:
        if need <= self.capacity:
            return
        cap = self.capacity
        while cap < need:
            cap *= 2
        for n, old in self.data.items():
            new = np.zeros((cap, *old.shape[1:]), old.dtype)
            new[: self.size] = old[: self.size]
            self.data[n] = new
        self.owner.extend([None] * (cap - self.capacity))
        entity = np.full(cap, -1, np.int64)
        entity[: self.size] = self.entity[: self.size]
        self.entity = entity
        born = np.full(cap, -1, np.int64)
        born[: self.size] = self.born[: self.size]
        self.born = born
        self.capacity = cap

    def alloc(self, n: int) -> np.ndarray:
        """``n`` rows: free ones first (lowest first), then fresh ones at the end."""
        take = min(n, len(self.free))
        rows = []
        if take:
            self.free.sort(reverse=True)
            rows = [self.free.pop() for _ in range(take)]
        fresh = n - take
        if fresh:
            self._grow(self.size + fresh)
            rows.extend(range(self.size, self.size + fresh))
            self.size += fresh
        return np.asarray(rows, np.intp)

    # -- membership -----------------------------------------------------------
    def attach(self, entities, comps) -> None:
        """Move ``comps`` (components of ``entities``, in private tables) into rows of this table."""
        n = len(comps)
        if not n:
            return
        rows = self.alloc(n)
        # group by source table so a bulk block moves in one array copy per field
        tables = list(map(_TABLE, comps))
        src_rows = np.fromiter(map(_ROW, comps), np.intp, n)
        if tables.count(tables[0]) == n:
            groups = [(tables[0], slice(None))]
        else:
            ids = np.fromiter(map(id, tables), np.int64, n)
            _, first, inverse = np.unique(ids, return_index=True, return_inverse=True)
            groups = [(tables[f], np.flatnonzero(inverse == k)) for k, f in enumerate(first.tolist())]
        for src, ks in groups:
            for name in self.fields:
                self.data[name][rows[ks]] = src.data[name][src_rows[ks]]
        for c, row in zip(comps, rows.tolist()):
            c._table = self
            c._row = row
        lo, hi = int(rows[0]), int(rows[-1]) + 1
        if hi - lo == n and (n == 1 or (np.diff(rows) == 1).all()):
            self.owner[lo:hi] = comps
        else:
            owner = self.owner
            for c, row in zip(comps, rows.tolist()):
                owner[row] = c
        self.entity[rows] = entities
        self.version += 1
        self.born[rows] = self.version
        self._by_entity = None

    def detach(self, rows) -> None:
        """Free ``rows``: their components get private copies of their values."""
        rows = [int(r) for r in rows]
        if not rows:
            return
        comps = [self.owner[r] for r in rows]
        private = Table(self.cls, len(rows))
        private.size = len(rows)
        idx = np.asarray(rows, np.intp)
        for name in self.fields:
            private.data[name][:] = self.data[name][idx]
        for k, (c, r) in enumerate(zip(comps, rows)):
            c._table = private
            c._row = k
            self.owner[r] = None
        self.entity[idx] = -1
        self.free.extend(rows)
        self.version += 1
        self._by_entity = None

    def detach_all(self) -> None:
        """Free every row (the world is closing): its components keep their values."""
        self.detach([r for r in range(self.size) if self.owner[r] is not None])

    def rows_of(self, entities: np.ndarray, what: str = "") -> np.ndarray:
        """Rows of ``entities`` (ids) in this table, in their order; a KeyError names a missing one."""
        if self._by_entity is None:
            live = np.flatnonzero(self.entity[: self.size] >= 0)
            ents = self.entity[live]
            order = np.argsort(ents, kind="stable")
            self._by_entity = (ents[order], live[order])
        ents, rows = self._by_entity
        entities = np.asarray(entities, np.int64)
        k = np.searchsorted(ents, entities)
        k = np.minimum(k, max(len(ents) - 1, 0))
        found = (ents[k] == entities) if len(ents) else np.zeros(len(entities), bool)
        if not found.all():
            bad = int(entities[np.flatnonzero(~found)[0]])
            raise KeyError(f"entity {bad} has no {self.cls.__name__}{what}")
        return rows[k]


class Columnar:
    """Base class of components whose fields live in a :class:`Table` row.

    Subclasses declare :class:`Field` attributes; ``__init__`` takes them as
    keyword (or positional, in declaration order) arguments, validates each,
    and fills a private one-row table until the component joins a World.
    """

    __slots__ = ("_table", "_row")
    _fields: dict[str, Field]

    def __init_subclass__(cls, **kw):
        super().__init_subclass__(**kw)
        fields = {}
        for klass in reversed(cls.__mro__):
            for name, attr in vars(klass).items():
                if isinstance(attr, Field):
                    fields[name] = attr
        cls._fields = fields

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        names = list(self._fields)
        if len(args) > len(names):
            raise TypeError(f"{type(self).__name__} takes at most {len(names)} positional arguments")
        values = dict(zip(names, args))
        for k, v in kwargs.items():
            if k not in self._fields:
                raise TypeError(f"{type(self).__name__} has no field {k!r}; fields: {', '.join(names)}")
            if k in values:
                raise TypeError(f"{type(self).__name__} got two values for {k!r}")
            values[k] = v
        coerced = {n: f.coerce(values.get(n, f.default)) for n, f in self._fields.items()}
        self._fill(coerced)

    def _fill(self, values: dict) -> None:
        table = Table(type(self), 1)
        table.size = 1
        for n, v in values.items():
            table.data[n][0] = v
        self._table = table
        self._row = 0

    @classmethod
    def bulk(cls, n: int, **columns: ArrayLike) -> list[Self]:
        """Create ``n`` components at once from arrays of shape ``(n, *field.shape)``.

        Every array is validated as a whole (the error names the first bad
        row); fields left out take their default. The block moves into a
        World's table in one copy per field.
        """
        n = int(n)
        if n < 0:
            raise ValueError(f"{cls.__name__}.bulk: n must be >= 0, got {n}")
        unknown = set(columns) - set(cls._fields)
        if unknown:
            raise TypeError(f"{cls.__name__} has no field(s) {sorted(unknown)}")
        table = Table(cls, max(n, 1))
        table.size = n
        for name, f in cls._fields.items():
            if name in columns:
                table.data[name][:n] = f.coerce_column(f"{cls.__name__}.{name}", columns[name], n)
            else:
                table.data[name][:n] = f.coerce(f.default)
        out = []
        new = object.__new__
        for row in range(n):
            obj = new(cls)
            obj._table = table
            obj._row = row
            out.append(obj)
        return out

    def values(self) -> dict:
        """The field values, as a dict of copies."""
        return {n: self._table.data[n][self._row].copy() for n in self._fields}

    @classmethod
    def _from_values(cls, values: dict):
        obj = object.__new__(cls)
        obj._fill({n: np.asarray(values[n], f.dtype) for n, f in cls._fields.items()})
        return obj

    def __copy__(self):
        return self._from_values(self.values())

    def __deepcopy__(self, memo):
        return self._from_values(self.values())

    def __reduce__(self):
        return type(self)._from_values, (self.values(),)

    def __repr__(self):
        parts = []
        for n, f in self._fields.items():
            v = getattr(self, n)
            parts.append(f"{n}={np.round(v, 6).tolist() if f.shape else v!r}")
        return f"{type(self).__name__}({', '.join(parts)})"

    def __eq__(self, other):
        if type(other) is not type(self):
            return NotImplemented
        return all(np.array_equal(self._table.data[n][self._row], other._table.data[n][other._row])
                   for n in self._fields)

    #: Components are mutable values: equal by value, so not hashable.
    __hash__ = None


_ROW = attrgetter("_row")
_TABLE = attrgetter("_table")
_FIRST = itemgetter(0)
_SECOND = itemgetter(1)


def in_sorted(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Which elements of ``a`` are in ``b``, which must be sorted ascending (a query's entities are):
    a binary search each (``np.isin`` sorts both and cost five times as much on a few dozen)."""
    if len(b) == 0:
        return np.zeros(len(a), bool)
    k = np.searchsorted(b, a)
    np.minimum(k, len(b) - 1, out=k)
    return b[k] == a


def as_index(rows: np.ndarray):
    """A slice when ``rows`` is one contiguous ascending run (much faster to gather), else ``rows``."""
    if len(rows) and rows[-1] - rows[0] == len(rows) - 1 and (len(rows) == 1 or np.all(np.diff(rows) == 1)):
        return slice(int(rows[0]), int(rows[-1]) + 1)
    return rows


def to_indices(rows) -> np.ndarray:
    """An index array from what :func:`as_index` returned (a slice or an array)."""
    if isinstance(rows, slice):
        return np.arange(rows.start, rows.stop)
    return np.asarray(rows)


class Columns:
    """The fields of one component class for a stated list of entities: gather and scatter.

    ``cols.entities`` is the entity order. Reading a field (``cols.linear``)
    gathers a *copy* of shape ``(n, *field.shape)`` in that order; assigning
    (``cols.linear = v``) validates the whole array (the error names the
    first bad row) and scatters it back. Made by
    :meth:`~driftframe.framework.world.World.columns` or :meth:`Query.columns`.
    """

    __slots__ = ("_table", "_rows", "entities")

    def __init__(self, table: Table, entities: np.ndarray, rows):
        object.__setattr__(self, "_table", table)
        object.__setattr__(self, "_rows", rows)
        object.__setattr__(self, "entities", entities)

    def __len__(self) -> int:
        return len(self.entities)

    def _field(self, name) -> Field:
        f = self._table.fields.get(name)
        if f is None:
            raise AttributeError(f"{self._table.cls.__name__} has no field {name!r}; "
                                 f"fields: {', '.join(self._table.fields)}")
        return f

    def __getattr__(self, name):
        self._field(name)
        out = self._table.data[name][self._rows]
        return out.copy() if isinstance(self._rows, slice) else out

    def __setattr__(self, name, value):
        f = self._field(name)
        arr = f.coerce_column(f"{self._table.cls.__name__}.{name}", value, len(self.entities))
        self._table.data[name][self._rows] = arr

    def __repr__(self):
        return f"<Columns {self._table.cls.__name__} of {len(self.entities)} entities>"


class Query:
    """Entities that have all of ``types`` (and, per entity, which of ``optional`` they have).

    Made by :meth:`~driftframe.framework.world.World.query` and cached there.
    :meth:`refresh` (call it at the top of ``process``) rebuilds the packed
    rows only when esper's query result changed; it returns True then.

    * ``entities``: ascending entity ids (an order that does not depend on
      esper's set order, so results do not either);
    * ``rows(T)``: rows into ``world.table(T).data[field]``, aligned with
      ``entities`` — a slice when contiguous. For an optional ``T`` an int
      array with -1 where the entity lacks it. For a plain (non-columnar)
      ``T``, the list of its component objects, aligned the same way;
    * ``columns(T)``: a :class:`Columns` over these entities.
    """

    def __init__(self, world, types: tuple, optional: tuple = ()):
        self.world = world
        self.types = types
        self.optional = optional
        self._list = None
        self._epoch = -1                    # the world's structure epoch this query was last refreshed at
        self.entities = np.empty(0, np.int64)
        self._rows: dict = {}
        self.version = 0

    def refresh(self) -> bool:
        world = self.world
        if access_check.running is not None:            # the checking mode: the running system declares these
            for T in self.types + self.optional:
                access_check.touched(T, "a query's refresh", world=world.name)
        world.sync()
        if world.epoch == self._epoch:      # no entity gained or lost a component since: same rows
            return False
        self._epoch = world.epoch
        lst = esper.get_components(*self.types)
        if lst is self._list:
            return False
        self._list = lst
        n = len(lst)
        ents = np.fromiter(map(_FIRST, lst), np.int64, n)
        order = np.argsort(ents, kind="stable")
        self.entities = ents = ents[order]
        comps = list(map(_SECOND, lst))
        rows = {}
        for k, T in enumerate(self.types):
            column = map(itemgetter(k), comps)
            if issubclass(T, Columnar):
                r = np.fromiter(map(_ROW, column), np.intp, n)[order]
                rows[T] = as_index(r) if n else r
            else:                                   # plain objects (ModelRef, Camera, ...)
                objs = list(column)
                rows[T] = [objs[i] for i in order.tolist()]
        for T in self.optional:
            r = np.full(n, -1, np.intp)
            if n:
                table = world.table(T)
                held = table.entity[: table.size]
                has = np.isin(ents, held[held >= 0])
                if has.any():
                    r[has] = table.rows_of(ents[has])
            rows[T] = r
        self._rows = rows
        self.version += 1
        return True

    def rows(self, T):
        return self._rows[T]

    def columns(self, T) -> Columns:
        """Gather/scatter ``T``'s fields for :attr:`entities`."""
        if T not in self.types:
            raise ValueError(f"{T.__name__} is not a required type of this query ({self.types})")
        return Columns(self.world.table(T), self.entities, self._rows[T])

    def __len__(self) -> int:
        return len(self.entities)
