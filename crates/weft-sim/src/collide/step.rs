//! One implicit step with contacts, shared by both solvers (`solver.solid`'s
//! [`crate::SolidStepper`] and the coupled solver's stage C): detect, solve, check every path
//! exactly, and solve again with the contacts the check added, Newton starting where the
//! last solve ended and ADMM from its impulses.

use super::solids::Solids;
use super::{CollisionSetup, Detector, MAX_ROUNDS, MAX_SEGMENT_ROUNDS, Room};
use crate::build::Compiled;
use crate::error::SimError;
use nalgebra::Vector3;
use std::sync::Arc;
use std::time::Instant;
use weft_scene::{SceneElement, Transform};
use weft_solid::integrator::{Contact, ContactSet};
use weft_solid::{Integrator, Settings, SolidSystem, State, StepError, StepStats};

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
        let held = self.contacts.capacity() as u64 * super::CONTACT_BYTES;
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
            ("contacts", self.room.contacts, super::CONTACT_BYTES)
        } else {
            (
                "pairs of primitives within reach",
                self.room.pairs,
                super::PAIR_BYTES,
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
        let t = Instant::now();
        self.detector.detect(
            setup,
            &c.ranges,
            &sys.pinned,
            &st.x,
            &st.v,
            (s0, s1, h),
            &mut self.contacts,
        );
        if let Some(solids) = &mut self.solids {
            solids.detect(setup, &sys.pinned, &st.x, &st.v, h, &mut self.contacts);
        }
        cs.detection_seconds += t.elapsed().as_secs_f64();
        self.overflowed()?;
        let mut round = 0;
        // The work of the rounds solved again, counted into the step's statistics.
        let mut discarded = StepStats::default();
        // The last solve's end: the next solve's first Newton iterate. The step is the same
        // minimization with a few more constraints (each solve starts from the step's start
        // state, its contacts linearized there), so the last answer is close to the next
        // and a solve from it takes a few iterations where one from the prediction took
        // them all again: re-solves were half of every contact example's Newton
        // iterations (cloth_pile 1,112 of 1,991, hair_on_head 418 of 790).
        let mut last: Option<Vec<Vector3<f64>>> = None;
        // And its impulses, for ADMM's multipliers: the check appends the contacts it adds,
        // so the last round's contacts keep their places (the added ones start at zero).
        // On top of the positions: cloth_pile 13.44 → 10.93 Newton iterations a step,
        // hair_pile 15.03 → 11.20.
        let mut impulses: Vec<[f64; 3]> = Vec::new();
        // And ADMM's scale σ of ρ where it ended: a round solved again has the last round's
        // contacts and a few more, so the scale ADMM balanced them at still suits them, where
        // starting at 1 walks down to it again (hair_on_head walks to 1e-4–1e-5 in its first
        // Newton iteration). Within the step only, so a step depends on its inputs alone.
        // Measured (24 frames, Newton iterations a step): hair_on_head 12.23 → 11.29,
        // hair_pile 12.18 → 10.87 (0 → 2 substeps retried), cloth_pile 12.39 → 11.71,
        // cloth_drape 14.20 → 14.25.
        let mut sigma = 0.0;
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
                    warm: &impulses,
                    guess: last.as_deref().or(guess),
                    sigma,
                    give_up: !last_try,
                    reach: self.reach,
                },
            )?;
            cs.admm_iterations += contact.admm_iterations;
            cs.admm_seconds += contact.admm_seconds;
            cs.pattern_rebuilds += usize::from(contact.pattern_rebuilt);
            cs.low_rank_joins += contact.low_rank_joins;
            let t = Instant::now();
            let checked = self.detector.check(
                setup,
                &c.ranges,
                &sys.pinned,
                &st.x,
                &trial.x,
                (s0, s1, h),
                &mut self.contacts,
            );
            let (mut added, mut penetration) = (checked.added, checked.deepest);
            let mut crossing = (0, 1.0);
            if let Some(solids) = &mut self.solids {
                let k = solids.check(
                    setup,
                    &sys.pinned,
                    &st.x,
                    &trial.x,
                    h,
                    settings.tolerance * h,
                    &mut self.contacts,
                );
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
            round += 1;
            // Past MAX_ROUNDS only while hair segments still get contacts (see
            // MAX_SEGMENT_ROUNDS), and only for them.
            let more = round < MAX_ROUNDS
                || (round < MAX_SEGMENT_ROUNDS
                    && checked.segments > 0
                    && checked.segments == added);
            if added == 0 || !more {
                if crossing.0 > 0 {
                    if !last_try {
                        cs.crossing_retries += 1;
                        return Err(StepError::Intersecting { pairs: crossing.0 });
                    }
                    // Back along the straight paths to the time they were proven apart;
                    // held vertices keep their targets.
                    cs.cut_backs += 1;
                    for (i, (x, x0)) in trial.x.iter_mut().zip(&st.x).enumerate() {
                        if !sys.pinned[i] {
                            *x = x0 + crossing.1 * (*x - x0);
                        }
                    }
                    for ((v, x), x0) in trial.v.iter_mut().zip(&trial.x).zip(&st.x) {
                        *v = (x - x0) / h;
                    }
                }
                cs.max_contacts = cs.max_contacts.max(self.contacts.len());
                cs.contacts += self.contacts.len();
                cs.max_penetration = cs.max_penetration.max(penetration);
                cs.max_residual = cs.max_residual.max(contact.max_residual);
                *st = trial;
                let mut step = step;
                step.absorb(&discarded);
                return Ok(step);
            }
            discarded.absorb(&step);
            cs.resolves += 1;
            last = Some(trial.x);
            impulses = contact.impulses;
            sigma = contact.sigma;
        }
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
