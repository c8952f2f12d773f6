"""Gravity: bodies on rails about one well (exact Kepler), or kick-drift-kick in the pull of many.

Runs in the movement stage after the movement system has predicted every
body's free flight (:mod:`driftframe.framework.step`) and writes the end of the
step of every body it integrates (marked :class:`~components.gravity.Orbiting`,
which the collision system leaves out: their sphere contacts are found here,
on their conics) into the step context, from the start of the step, which the
components still hold: its result replaces the prediction, and the commit
stage writes it. A scene without a :class:`~components.gravity.GravityWell`
costs one empty esper query per step.

**Layout** (one concept per module, as REBOUND keeps one integrator per file):
``system`` (:class:`GravitySystem`: gathers the wells and bodies, runs each
step's stages in order), ``context`` (:class:`~.context.GravityStep`, the step
handed from stage to stage: ``t0``, ``t1`` and ``dt`` exactly as given, the
start states, the outputs; and the named records the stages pass), ``wells``,
``rails`` (epochs, thrust, surface bounces), ``crossings`` (spheres of
influence), ``nbody``, ``movers`` and ``contacts`` (the sphere-contact pass) and
``lookahead`` (what the system predicts). The system is composed of one part
class per module; each part's methods take the step context, never a stash of
the last one (the look-ahead alone evaluates from the last step). What other
systems need of it they read from the
:class:`~driftframe.framework.orbit_state.OrbitState` resource it publishes.

**Which well (patched conics).** A body moves about the deepest well whose
sphere of influence holds it (a root well's is infinite; a moon's is Laplace's
``a (m/M)^(2/5)`` unless given); ties at one depth go to the strongest pull
``mu/d^2``. Inside a moon's sphere the body's state is taken relative to the
moon, which follows its own conic about its parent. A body on rails changes
sphere *within* the step, at the exact time its conic crosses the sphere
(into a moon's: where its conic about the parent first comes within ``soi`` of
the moon's, by the conservative advancement of the sphere contacts below; out
of one: the outward crossing of ``soi`` on its conic about the moon,
:func:`framework.kepler.time_to_radius` with ``outward=True``), and goes on
from there about the new well: so a long step cannot carry a ship through a
moon (it meets the moon's surface at the time a short step finds), and the
patched-conic path is the same at every step length. A collider's crossings
are events of the contact pass below, in time order with its contacts (a
contact just before a crossing is met on the old conic, and a new conic looks
for its crossing again); another body makes at most :data:`MAX_CROSSINGS` a
step, and one after a surface bounce in the same step at the next step's start.

**Modes, per body, vectorised over all bodies of a well:**

* *On rails* (the default): the exact two-body flow about the well
  (:func:`framework.kepler.propagate`, universal variables), evaluated each
  step from the body's *epoch* — its state about the well at the last time
  something changed it — for the whole time since. Errors therefore never
  build up: energy and angular momentum stay at one rounding however long it
  runs (``benchmarks/orbit_accuracy.py``), and the state at a time ``t`` does
  not depend on how the time was stepped (time warp changes nothing). A new
  epoch is taken when the body thrusts, touches a surface, changes sphere of
  influence, or when anything else (a collision, user code) changed its
  position or velocity since this system wrote them. A step in which none of
  that happens to any body of a lone root well (and no sphere contact is looked
  for) is one compiled pass from :data:`framework.kepler.COMPILED_MIN` bodies
  on (``rails.Rails._quiet``), with the stages' bits.
* *Thrust* (the rule when the engine fires): a body whose
  :class:`~components.body.Acceleration` is non-zero this step takes the
  symplectic split ``v += a dt/2; Kepler flow for dt; v += a dt/2`` — a
  kick-drift-kick with the thrust as the kick and the exact orbit as the
  drift. It is second order in ``dt`` for the thrust, adds exactly
  ``a dt`` to the velocity (a timed burn delivers the Δv it asks for), and
  is the exact orbit again the step the engine stops: the body goes straight
  back on rails from its new state. No mode flag is kept, so nothing can
  fall out of step.
* *n-body* (opt-in, :class:`~components.gravity.NBody`): kick-drift-kick
  (symplectic, second order) in the pull of every well and of every other
  ``NBody`` body's :class:`~components.body.Mass` (``G m``, pairwise,
  O(n^2)). About a scene's one root well, a body whose conic clears the
  surface drifts on that conic (Wisdom–Holman,
  :mod:`framework.wisdom_holman`: exact for a lone body at any step) unless
  it has a collider in a step with a contact pass (another collider or an
  obstacle in the scene): those, and every n-body body in a scene of
  several wells, drift on straight lines (leapfrog), where sphere contacts
  are found exactly. Two bodies on their conics that pass close (within a
  few Hill radii) switch smoothly to an adaptive integrator for the pass
  (:mod:`framework.mercurius`, REBOUND's MERCURIUS scheme). Without a well,
  ``NBody`` bodies pull each other on a drift-kick-drift leapfrog.

**Surfaces.** A body on rails that reaches a well's surface sphere within the
step is found exactly on its conic (:func:`framework.kepler.time_to_radius`;
no sampling, so nothing tunnels at any speed or warp): it is advanced to the
contact, its radial velocity relative to the well reversed (elastic: kinetic
energy relative to the well, hence the orbit energy, kept to rounding), and
advanced for the rest of the step. n-body bodies sweep the straight drift of
their step against each sphere: a root well's moves straight too (a
quadratic), a moon's on its conic (conservative advancement on both paths).
Each contact is a
:class:`~components.gravity.SurfaceContact` in ``world.events``.

**Sphere contacts.** Every :class:`~components.collision.SphereCollider`
this system moves or meets takes part in one contact pass per step
(:meth:`GravitySystem._contacts`), in time order, exact on each body's own
path (the collision system leaves every ``Orbiting`` body out: it moves its
colliders along straight chords). The *movers*: colliders on rails (each on
its conic about its well, which is itself at rest, moving straight, or a moon
on its conic about its parent), n-body colliders (on the leapfrog's straight
drift between its two kicks), and *obstacles*, the colliders this system does
not move (``Mass(inf)``, or no ``Velocity``; not a well): straight at their
step-start velocity (the movement stage's prediction moves them; an
``Acceleration`` on one is not followed here). Only
where two or more colliders move, or one and an obstacle, is anything done; a
scene without colliders pays one comparison. Each step, after the
end-of-step states on rails are known:

1. *Swept boxes* (world frame): for a body on rails
   :func:`framework.kepler.arc_boxes` about its well (the box of its start and
   end, grown by its radius and by ``A h^2 / 8``, how far a path with
   acceleration at most ``A = mu / rho^2`` can leave its chord in ``h``;
   ``rho``: the nearer end's distance, or the periapsis where an apsis is
   passed, never under the surface radius; a body that touches the surface in
   the step, or came into the well's sphere in it, gets the cube it can reach
   at its top speed), moved by the box of the well centre's own path; a line's
   box of its two ends. Candidate pairs from
   :func:`framework.broadphase.box_pairs`; pairs on rails about one well less
   those whose separation's chord stays farther apart than the same bound
   allows (``_near``).
2. *Times of contact*, vectorised over the pairs, by conservative advancement
   on the gap ``|x_b - x_a| - (R_a + R_b)``, each step the largest that cannot
   pass a contact (from the closing rate and a bound on the relative
   acceleration), Newton's step near contact; exact to ~1e-12 relative at any
   step length or warp. Two bodies on rails about one well: their conics about
   it from their epochs, the bound the two pulls or the tidal
   ``2 mu |d| / rho^3`` for bodies close together
   (:func:`framework.kepler.time_to_touch`). A body on rails about a *root* well
   against a line: the line relative to the well, which moves straight too
   (``line_b=True``). Every other pair (bodies about different wells, a body
   about a moon against an obstacle, rails against n-body, two n-body bodies):
   the world-frame paths, the bound the sum of each body's pull and its well
   centre's (:func:`framework.kepler.time_to_touch_paths`). Only approaching
   pairs touch; a pair is followed from both bodies' last contacts up to the
   first surface contact of a body on rails in it.
3. *Contacts in time order*, together with the surface contacts of the
   colliders on rails: the impulse along the line of centres (masses from
   ``Mass``, 1 kg without, an obstacle's inverse mass 0; restitution the smaller
   of the two colliders', as in the collision system); a new epoch at the
   contact for a body on rails (so the rails stay exact: energy kept to
   rounding, momentum of the pair to rounding), a new drift line for an n-body
   body; new swept boxes from the contact on, their pairs looked at again and
   new ones found; a :class:`~components.collision.CollisionEvent` (fields as
   the collision system's, lower entity first, ``method="kepler"`` where a body
   on rails is in it, else ``"leapfrog"``) in ``world.events``. The bodies on
   rails touched get their end-of-step state from their new epochs.

A *resting* contact (``e = 0``, or any contact after which the pair separates
slower than the pulls between them could undo within the step) is not looked
at again in that step: the next step resolves it afresh, so a pair pressed
together by the tidal field costs one small impulse per step (no position
correction: it may sink into itself by what that pull does over a step,
``~3 mu d dt^2 / (2 r^3)``, while it presses). A resting contact on an obstacle
(the well's pull presses the body on, and the obstacle feels none of it)
separates at the least speed that keeps the pair apart to the step's end,
``A (t1 - tc) / 2``, instead of sinking in by ``A dt^2 / 2`` a step: the body
hops by at most ``A dt^2 / 8``. A body meets at most
:data:`MAX_SPHERE_CONTACTS` contacts in a step (further ones in that step are
not looked for, with a warning); a pair that grazes too slowly to converge
(``g' -> 0`` as ``g -> 0``) is taken to touch where it is within 1e-6 of
``R_a + R_b``, else left for the step with a warning. An n-body collider's
surface contacts are events of the same pass (its drift line against a root
well in closed form, against a moon by conservative advancement), so a body that
bounces off a surface meets what lies on its new path in the same step; an
n-body body without a collider sweeps its drift against the surfaces after it.

**Not modelled:** a well's own collider (bodies meet its surface radius; a
``SphereCollider`` of another radius on a well is not used, with a warning).
The warp governor's look-ahead (:meth:`GravitySystem.next_contact`,
:meth:`GravitySystem.next_sphere_contact`) predicts every contact of a body on
rails: its surface contacts, and its sphere contacts with bodies on rails
about any well and with obstacles. An n-body body's path is not known beyond
its step: for its sphere contacts the look-ahead gives a lower bound on when
it could first touch (the gap at the pair's speed plus the most the pulls can
add), so the warp drops before such a contact, perhaps early, never late.

**Checks** (the first step, and whenever wells or bodies are added): a well
inside another's surface, a moon whose parent is missing or not a well, and
a body starting inside a surface are errors naming the entities and values.

Frames: wells' positions come from their ``Transform``; a root well moves at
its own constant ``Velocity`` if it has one (the movement system moves it),
and a moon's state about its parent is its ``Transform``/``Velocity`` minus
the parent's. Bodies with infinite :class:`~components.body.Mass` are
kinematic obstacles and are left to the movement system.
"""
from driftframe.systems.gravity.contacts import MAX_SPHERE_CONTACTS
from driftframe.systems.gravity.crossings import MAX_CROSSINGS
from driftframe.systems.gravity.movers import SWEEP_OVERLAPS
from driftframe.systems.gravity.rails import MAX_CONTACTS
from driftframe.systems.gravity.system import GravitySystem

__all__ = ["GravitySystem", "MAX_CONTACTS", "MAX_CROSSINGS", "MAX_SPHERE_CONTACTS", "SWEEP_OVERLAPS"]
