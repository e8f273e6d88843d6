//! One implicit step with contacts, shared by both solvers (`solver.solid`'s
//! [`crate::SolidStepper`] and the coupled solver's stage C): detect, solve, check every path
//! exactly, and solve again with the contacts the check added, Newton starting where the
//! last solve ended and ADMM from its impulses.

use super::detect::Detector;
use super::room::{CONTACT_BYTES, PAIR_BYTES, Room};
use super::setup::CollisionSetup;
use super::solids::Solids;
use crate::build::Compiled;
use crate::error::SimError;
use nalgebra::Vector3;
use std::ops::Range;
use std::sync::Arc;
use std::time::Instant;
use weft_scene::{SceneElement, Transform};
use weft_solid::integrator::{Contact, ContactSet, ContactStats};
use weft_solid::{Integrator, Settings, SolidSystem, State, StepError, StepStats};

/// Rounds of exact checking allowed per step before the step is accepted as it is (and its
/// penetration reported).
const MAX_ROUNDS: usize = 4;
/// Rounds allowed while the last check still added hair segment contacts. A segment sliding
/// over a faceted collider is linearized at one point a round, and the point that ends
/// deepest moves along the segment from round to round (hair_on_head, frame 12: 0.30, 0.32,
/// 0.22 mm at s = 0.36, 0.50, 0.62 of one segment); four rounds let a step end a segment
/// 0.1 mm inside the 2 mm kept whenever the solves' rounding changed. Eight rounds for every
/// contact cost the cloth pile 20 % for nothing; segments alone need them.
const MAX_SEGMENT_ROUNDS: usize = 8;

/// What contacts cost and did over a frame (or a coupling iteration).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ContactFrameStats {
    /// Most contacts in one step.
    pub max_contacts: usize,
    /// Contacts summed over steps.
    pub contacts: usize,
    /// ADMM iterations summed over steps (and their re-solves).
    pub admm_iterations: usize,
    /// Re-solves after the exact check found a path the contacts missed.
    pub resolves: usize,
    /// Largest penetration at the end of a step, measured by the exact check [m].
    pub max_penetration: f64,
    /// Largest distance from Coulomb's law at a step's end [m/s].
    pub max_residual: f64,
    /// Seconds finding contacts (detection and exact checks).
    pub detection_seconds: f64,
    /// Of `detection_seconds`, between deforming solids: refitting the trees and traversing
    /// them (broad phase).
    pub broad_seconds: f64,
    /// Of `detection_seconds`, between deforming solids: distances and closest points before
    /// a step (narrow phase).
    pub narrow_seconds: f64,
    /// Of `detection_seconds`, between deforming solids: continuous detection of every path
    /// after a solve.
    pub ccd_seconds: f64,
    /// Seconds in the ADMM loops (their solves, contact projections and refactorizations).
    pub admm_seconds: f64,
    /// Steps retried with a smaller step because continuous detection found primitives of
    /// the solids passing through each other after the last re-solve.
    pub crossing_retries: usize,
    /// Steps cut back to the last time continuous detection proved free of crossings (at
    /// the smallest step allowed, or in a coupling iteration, which is not retried).
    pub cut_backs: usize,
    /// Most pairs of primitives found touching at a step's start (their crossing cannot be
    /// judged: a scene that starts intersecting).
    pub started_inside: usize,
    /// Steps whose solves rebuilt the system's pattern for contacts between solids (blocks
    /// between vertices that share no element), counted per solve.
    pub pattern_rebuilds: usize,
    /// ADMM rounds whose contacts rejoining the split were added to the kept factor as a
    /// low-rank correction, not refactorized.
    pub low_rank_joins: usize,
}

/// The contact machinery of a compiled scene that has contact pairs: the detector and the
/// step's contact list (reused buffers; no simulation state, so a step depends only on its
/// inputs).
pub struct Contacts {
    compiled: Arc<Compiled>,
    detector: Detector,
    solids: Option<Solids>,
    contacts: Vec<Contact>,
    /// ADMM iterations allowed per Newton iteration.
    pub max_admm: usize,
    /// The smallest distance any pair keeps between its surfaces [m] (`ContactSet::reach`).
    reach: f64,
    /// What detection may hold a step, and what to change when it is not enough.
    room: Room,
    room_hint: String,
}

impl Contacts {
    /// The machinery for `compiled` as its colliders are in `scene`, its contact lists held
    /// within a share of `max_bytes` ([`Room`]); `None` when the scene has no contact pairs
    /// (nothing is built).
    pub fn new(
        compiled: Arc<Compiled>,
        scene: &[SceneElement],
        max_admm: usize,
        max_bytes: Option<u64>,
    ) -> Option<Self> {
        let setup = compiled.collisions.as_ref()?;
        let room = Room::within(max_bytes);
        let detector = Detector::new(setup, scene, room.contacts);
        let solids = Solids::new(setup, &compiled.ranges, room);
        let reach = setup
            .pairs
            .iter()
            .map(|p| p.distance)
            .chain(setup.solid_pairs.iter().map(|p| p.distance))
            .fold(f64::INFINITY, f64::min);
        Some(Contacts {
            reach,
            room,
            room_hint: widest_band(setup, scene),
            compiled,
            detector,
            solids,
            contacts: Vec::new(),
            max_admm,
        })
    }

    /// Says how much more the process may allocate now [bytes]: the room of a step's
    /// contact lists becomes a share of that and of what they already hold.
    pub fn set_available(&mut self, available: u64) {
        let held = self.contacts.capacity() as u64 * CONTACT_BYTES;
        let bytes = available.saturating_add(held);
        self.room = Room::within(Some(bytes));
        self.detector.set_room(self.room.contacts);
        if let Some(s) = &mut self.solids {
            s.set_room(self.room);
        }
    }

    /// The error for detection that stopped at its room (contacts, or candidate pairs of
    /// primitives between solids, past the memory allowed), if it did since the last call.
    fn overflowed(&mut self) -> Result<(), StepError> {
        let solids = self.solids.as_mut().is_some_and(|s| s.take_overflow());
        if !(self.detector.take_overflow() | solids) {
            return Ok(());
        }
        let (what, count, each) = if self.contacts.len() >= self.room.contacts {
            ("contacts", self.room.contacts, CONTACT_BYTES)
        } else {
            (
                "pairs of primitives within reach",
                self.room.pairs,
                PAIR_BYTES,
            )
        };
        Err(StepError::ContactsTooMany {
            what,
            count,
            limit_gib: (count as f64 * each as f64) / (1u64 << 30) as f64,
            hint: self.room_hint.clone(),
        })
    }

    /// Before stepping a frame: the colliders' transforms at its start (`from`) and end
    /// (`to`), and their shapes in `scene` (the frame's end).
    pub fn frame(
        &mut self,
        scene: &[SceneElement],
        from: &[Option<Transform>],
        to: &[Option<Transform>],
    ) -> Result<(), SimError> {
        let setup = self.compiled.collisions.as_ref().expect("checked in new");
        self.detector.frame(setup, scene, from, to)
    }

    /// One implicit step of `h` of `sys` from `st` (replaced by the end state) between
    /// fractions `s0` and `s1` of the frame, held vertices at `targets`, Newton from `guess`
    /// when given: contacts detected from the start, then the exact check of every path after
    /// each solve adds the contacts it missed and the step is solved again, its Newton
    /// starting at the last solve's end and its ADMM from that solve's impulses (at most
    /// `MAX_ROUNDS` solves, `MAX_SEGMENT_ROUNDS` while only hair segments get contacts; the
    /// last one's penetration is reported; the statistics count every solve). If
    /// primitives of the solids still pass through each other, the step fails with
    /// [`StepError::Intersecting`] so that the caller retries it smaller, unless `last_try`:
    /// then the free vertices are cut back to the last time continuous detection proved safe.
    /// Unless `last_try`, a solve whose ADMM stalls once Newton has converged fails early
    /// too (`ContactSet::give_up`), for the same retry.
    /// Counts go to `cs`.
    #[allow(clippy::too_many_arguments)]
    pub fn step(
        &mut self,
        integrator: &mut Integrator,
        sys: &SolidSystem,
        st: &mut State,
        targets: Option<&[Vector3<f64>]>,
        guess: Option<&[Vector3<f64>]>,
        (s0, s1, h): (f64, f64, f64),
        settings: &Settings,
        last_try: bool,
        cs: &mut ContactFrameStats,
    ) -> Result<StepStats, StepError> {
        let compiled = self.compiled.clone();
        let c = &*compiled;
        let setup = c.collisions.as_ref().expect("checked in new");
        self.detect_start(setup, &c.ranges, &sys.pinned, st, (s0, s1, h), cs)?;
        let mut round = 0;
        // The work of the rounds solved again, counted into the step's statistics.
        let mut discarded = StepStats::default();
        let mut warm = Warm::default();
        loop {
            let mut trial = st.clone();
            let (step, contact) = integrator.step_contacts(
                sys,
                &mut trial,
                targets,
                h,
                settings,
                ContactSet {
                    contacts: &self.contacts,
                    max_admm: self.max_admm,
                    warm: &warm.impulses,
                    guess: warm.last.as_deref().or(guess),
                    sigma: warm.sigma,
                    give_up: !last_try,
                    reach: self.reach,
                },
            )?;
            count_solve(&contact, cs);
            let checked = self.check_round(
                setup,
                &c.ranges,
                &sys.pinned,
                (&st.x, &trial.x),
                (s0, s1, h),
                settings.tolerance * h,
                cs,
            )?;
            round += 1;
            if checked.added == 0 || !more_rounds(round, checked.segments, checked.added) {
                let (crossing, toi) = checked.crossing;
                if crossing > 0 {
                    if !last_try {
                        cs.crossing_retries += 1;
                        return Err(StepError::Intersecting { pairs: crossing });
                    }
                    cs.cut_backs += 1;
                    cut_back(&mut trial, st, &sys.pinned, toi, h);
                }
                cs.max_contacts = cs.max_contacts.max(self.contacts.len());
                cs.contacts += self.contacts.len();
                cs.max_penetration = cs.max_penetration.max(checked.penetration);
                cs.max_residual = cs.max_residual.max(contact.max_residual);
                *st = trial;
                let mut step = step;
                step.absorb(&discarded);
                return Ok(step);
            }
            discarded.absorb(&step);
            cs.resolves += 1;
            warm = Warm {
                last: Some(trial.x),
                impulses: contact.impulses,
                sigma: contact.sigma,
            };
        }
    }

    /// The contacts of a step from `st`, detected before it is solved (against the colliders,
    /// then between the solids), replacing the last step's.
    fn detect_start(
        &mut self,
        setup: &CollisionSetup,
        ranges: &[Option<Range<usize>>],
        pinned: &[bool],
        st: &State,
        (s0, s1, h): (f64, f64, f64),
        cs: &mut ContactFrameStats,
    ) -> Result<(), StepError> {
        let t = Instant::now();
        self.detector.detect(
            setup,
            ranges,
            pinned,
            &st.x,
            &st.v,
            (s0, s1, h),
            &mut self.contacts,
        );
        if let Some(solids) = &mut self.solids {
            solids.detect(setup, pinned, &st.x, &st.v, h, &mut self.contacts);
        }
        cs.detection_seconds += t.elapsed().as_secs_f64();
        self.overflowed()
    }

    /// The exact check after a solve that took the step from `x0` to `x1`: the contacts it
    /// adds are appended to the step's, and what it found is returned. `tol`: the distance a
    /// contact met to the solver's tolerance may leave over the step (`Solids::check`).
    #[allow(clippy::too_many_arguments)]
    fn check_round(
        &mut self,
        setup: &CollisionSetup,
        ranges: &[Option<Range<usize>>],
        pinned: &[bool],
        (x0, x1): (&[Vector3<f64>], &[Vector3<f64>]),
        (s0, s1, h): (f64, f64, f64),
        tol: f64,
        cs: &mut ContactFrameStats,
    ) -> Result<Round, StepError> {
        let t = Instant::now();
        let checked = self.detector.check(
            setup,
            ranges,
            pinned,
            x0,
            x1,
            (s0, s1, h),
            &mut self.contacts,
        );
        let (mut added, mut penetration) = (checked.added, checked.deepest);
        let mut crossing = (0, 1.0);
        if let Some(solids) = &mut self.solids {
            let k = solids.check(setup, pinned, x0, x1, h, tol, &mut self.contacts);
            added += k.added;
            penetration = penetration.max(k.deepest);
            crossing = (k.crossing, k.toi);
            cs.started_inside = cs.started_inside.max(k.started_inside);
        }
        cs.detection_seconds += t.elapsed().as_secs_f64();
        self.overflowed()?;
        if let Some(solids) = &mut self.solids {
            let times = solids.take_times();
            cs.broad_seconds += times.broad;
            cs.narrow_seconds += times.narrow;
            cs.ccd_seconds += times.ccd;
        }
        Ok(Round {
            added,
            segments: checked.segments,
            penetration,
            crossing,
        })
    }
}

/// Where a round solved again starts from: the last solve's end, impulses and ADMM scale.
/// Within the step only, so a step depends on its inputs alone.
#[derive(Default)]
struct Warm {
    /// The last solve's end: the next solve's first Newton iterate. The step is the same
    /// minimization with a few more constraints (each solve starts from the step's start
    /// state, its contacts linearized there), so the last answer is close to the next
    /// and a solve from it takes a few iterations where one from the prediction took
    /// them all again: re-solves were half of every contact example's Newton
    /// iterations (cloth_pile 1,112 of 1,991, hair_on_head 418 of 790).
    last: Option<Vec<Vector3<f64>>>,
    /// And its impulses, for ADMM's multipliers: the check appends the contacts it adds,
    /// so the last round's contacts keep their places (the added ones start at zero).
    /// On top of the positions: cloth_pile 13.44 → 10.93 Newton iterations a step,
    /// hair_pile 15.03 → 11.20.
    impulses: Vec<[f64; 3]>,
    /// And ADMM's scale σ of ρ where it ended: a round solved again has the last round's
    /// contacts and a few more, so the scale ADMM balanced them at still suits them, where
    /// starting at 1 walks down to it again (hair_on_head walks to 1e-4–1e-5 in its first
    /// Newton iteration). 0 for the first solve (ADMM starts at 1). Measured (24 frames,
    /// Newton iterations a step): hair_on_head 12.23 → 11.29, hair_pile 12.18 → 10.87
    /// (0 → 2 substeps retried), cloth_pile 12.39 → 11.71, cloth_drape 14.20 → 14.25.
    sigma: f64,
}

/// What a round's exact check found, against the colliders and between the solids.
struct Round {
    /// Contacts added.
    added: usize,
    /// Of those, hair segments' against colliders.
    segments: usize,
    /// The largest penetration at the solve's end [m].
    penetration: f64,
    /// Pairs of primitives of the solids still crossing, and the fraction of the step along
    /// the straight paths at which they were last proven apart.
    crossing: (usize, f64),
}

/// A solve's ADMM counts, into the frame's.
fn count_solve(contact: &ContactStats, cs: &mut ContactFrameStats) {
    cs.admm_iterations += contact.admm_iterations;
    cs.admm_seconds += contact.admm_seconds;
    cs.pattern_rebuilds += usize::from(contact.pattern_rebuilt);
    cs.low_rank_joins += contact.low_rank_joins;
}

/// Whether a check that added contacts after solve `round` (`segments` of the `added`
/// against colliders by hair segments) gets the step solved again: past MAX_ROUNDS only
/// while hair segments still get contacts (see MAX_SEGMENT_ROUNDS), and only for them.
fn more_rounds(round: usize, segments: usize, added: usize) -> bool {
    round < MAX_ROUNDS || (round < MAX_SEGMENT_ROUNDS && segments > 0 && segments == added)
}

/// Back along the straight paths from `st` to `trial`'s end, to fraction `toi` of the step
/// where they were proven apart; held vertices keep their targets. Velocities are the
/// step's new displacement over `h`.
fn cut_back(trial: &mut State, st: &State, pinned: &[bool], toi: f64, h: f64) {
    for (i, (x, x0)) in trial.x.iter_mut().zip(&st.x).enumerate() {
        if !pinned[i] {
            *x = x0 + toi * (*x - x0);
        }
    }
    for ((v, x), x0) in trial.v.iter_mut().zip(&trial.x).zip(&st.x) {
        *v = (x - x0) / h;
    }
}

/// What to change when a step's contacts outgrow their room: the widest contact band, whose
/// pair it is and where its width comes from.
fn widest_band(setup: &CollisionSetup, scene: &[SceneElement]) -> String {
    let name = |e: usize| scene.get(e).map_or("?", |e| e.name.as_str());
    let widest = setup
        .pairs
        .iter()
        .map(|p| {
            let c = setup.colliders[p.collider].element;
            (
                p.distance,
                format!("'{}' against '{}'", name(p.element), name(c)),
            )
        })
        .chain(setup.solid_pairs.iter().map(|p| {
            let with = if p.a == p.b {
                format!("'{}' against itself", name(p.a))
            } else {
                format!("'{}' against '{}'", name(p.a), name(p.b))
            };
            (p.distance, with)
        }))
        .max_by(|a, b| a.0.total_cmp(&b.0));
    match widest {
        Some((d, with)) => format!(
            "the widest contact band is {d} m, {with} (both sides' collider.thickness): a \
             thinner band keeps fewer primitives in reach of each other"
        ),
        None => String::new(),
    }
}
