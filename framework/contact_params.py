"""The contact solver's tolerances, bounds, flag bits and stats layout (see :mod:`.contact`).

Read by the compiled kernels at compile time (numba freezes a global's value into the code), so this
module is in the kernel cache's key (:data:`driftframe.framework.kernels.KERNEL_IMPORTS`).
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

#: Pairs whose contact is within ``TOUCH R / |v_n|`` of an instant meet at that instant (gap < TOUCH R).
TOUCH = 1e-9
#: Normal approach speeds below this fraction of the pair's own speeds (|u_i| + |u_j|) are rounding noise.
APPROACH = 1e-12
#: Centres closer than this fraction of r_i + r_j define no contact normal: such a pair is left to pass.
CENTRED = 1e-9
#: Longest time window (fraction of dt) one wave collects contacts over.
SLACK_MAX = 1e-9
#: Islands up to this many contacts are solved simultaneously; larger ones contact by contact.
DENSE_MAX = 32
#: Waves in a burst (each within t_c of the previous) before a body's contacts lose their bounce.
JAM = 256
#: Default cap on one body's contacts in one step (then e = 0; at twice this its island sticks).
CAP = 8
#: Default t_c of the TC model, as a fraction of dt.
TC = 1e-6

#: flags returned by the solvers (:func:`~.contact_solve.solve_all_pairs`, :func:`~.contact_solve.solve_listed`):
#: a body's burst passed JAM waves (its contacts lost their bounce)
F_JAM = 1
#: the TC model took a rapid inelastic repeat as elastic
F_TC = 2
#: a body passed ``cap`` inelastic contacts this step (its contacts lost their bounce)
F_CAP = 4
#: an island's touching cluster was given one velocity (the jam path)
F_STICK = 8
#: the step's wave limit was reached: contacts left unresolved
F_LIMIT = 16
#: more bodies were swept than the list's budget: rebuild it
F_REBUILD = 32
#: the step needs the jam path, or an island of more than DENSE_MAX contacts (island_sequential): run it again
#: with the _stick variant, which has both (the inputs are as they came)
F_AGAIN = 64

#: the solvers' stats array, index by index: candidate pairs, contacts, waves, bodies swept, overlapping
#: pairs at the start, the deepest one's bodies i and j and its centres' distance / (r_i + r_j), islands
#: solved contact by contact, heap entries popped into a wave, pushed, put back
(S_PAIRS, S_CONTACTS, S_WAVES, S_SWEPT, S_OVERLAPS, S_WORST_I, S_WORST_J, S_WORST, S_SEQUENTIAL, S_POPPED,
 S_PUSHED, S_BACK) = range(12)
#: the length of the stats array
N_STATS = 12

# _NOT_LITERAL: a constant passed from one kernel to another (``f(0)``, or ``k = 0`` then ``f(k)``)
# is typed Literal[int](0) at first, and numba compiles the callee for it and again for int64
# once ``k`` widens (True and False each get their own, too). Constants that reach a callee are
# written np.int64(0) / np.bool_(True): one compile each (what a literal cost: docs/design/contact.md).


class ListedArrays(NamedTuple):
    """The neighbour list's arrays a step reads (:class:`~.broadphase_list.NeighbourList`) and its scratch."""

    #: (n,) bool: bodies the list does not speak for (their paths are tested each step); changed in place
    swept: np.ndarray
    #: (n, 3) path boxes of the swept bodies (lower, upper corner, m); changed in place
    blo: np.ndarray
    bhi: np.ndarray
    #: (3, n) build centres, (n,) skins and reaches (m): :meth:`NeighbourList.kernel_arrays`
    centre: np.ndarray
    skin: np.ndarray
    reach: np.ndarray
    #: the territories' x order, their sorted low ends, twice the largest listed reach
    order: np.ndarray
    lo_x: np.ndarray
    width: float
    #: swept bodies before F_REBUILD
    budget: int
    #: scratch: (n,), (n, 3), (n, 3)
    tosweep: np.ndarray
    newlo: np.ndarray
    newhi: np.ndarray
