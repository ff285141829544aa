//! Batches of rays, and the passes' way of casting them.
//!
//! In: a [`RayBatch`]: per ray an origin, a unit direction and a max
//! distance, or a *blocked* ray (a receiver's direction below its own
//! surface, occluded by definition and traced by no backend; it keeps its
//! place so the answers line up with the receiver's sequence). Out: one
//! answer per ray in the batch's order ([`Tracer::occluded_batch`]).
//!
//! [`for_each_receiver`] is how a pass casts rays: each receiver of a
//! chunk emits its rays into one batch, the tracer answers the batch, and
//! each receiver then reads its rays' directions and answers, in the order
//! it emitted them. The answers do not depend on how the batch is split or
//! ordered, so a pass's sums (added in each receiver's own order) are the
//! same bytes as when it called the tracer ray by ray, on any thread count.

use super::backend::{Accelerator, Offer};
use super::{Hit, RayBatch, Tracer};
use glam::Vec3;
use rayon::prelude::*;

/// Rays of a batch traced one after the other by one worker: a large batch
/// is split into pieces of this many, traced in parallel.
const PIECE: usize = 4096;

/// Receivers to a batch at least when an accelerator answers them: tens
/// of thousands of rays a dispatch in a pre-pass round, up to a million
/// in the adaptive pass (32 MB of rays per worker at its most).
const ACCELERATED_RECEIVERS: usize = 4096;

/// What a batch asks of each ray, and the answer's type.
pub trait Query: Sync {
    type Answer: Copy + Default + Send + Sync;
    /// Ray `i` of `rays`, not blocked.
    fn answer(tracer: &Tracer, rays: &RayBatch, i: usize) -> Self::Answer;
    /// A blocked ray's answer.
    const BLOCKED: Self::Answer;
    /// Offers rays `from..` of the batch to `accelerator` (attached to
    /// `tracer`), which answers them into `out` (one a ray from `from`) if
    /// it takes them.
    fn offer(
        accelerator: &dyn Accelerator,
        tracer: &Tracer,
        rays: &RayBatch,
        from: usize,
        out: &mut [Self::Answer],
    ) -> Offer;
}

/// Whether anything is hit in (0, t_max] (a blocked ray: true).
pub struct Occlusion;

impl Query for Occlusion {
    type Answer = bool;
    const BLOCKED: bool = true;
    #[inline]
    fn answer(tracer: &Tracer, rays: &RayBatch, i: usize) -> bool {
        tracer.occluded(rays.origins[i], rays.directions[i], rays.t_max[i])
    }
    fn offer(
        accelerator: &dyn Accelerator,
        tracer: &Tracer,
        rays: &RayBatch,
        from: usize,
        out: &mut [bool],
    ) -> Offer {
        accelerator.occluded_from(tracer, rays, from, out)
    }
}

/// The closest hit in (0, t_max], cut at the ray's depth (a blocked ray:
/// none, as it is no ray).
pub struct Closest;

impl Query for Closest {
    type Answer = Option<Hit>;
    const BLOCKED: Option<Hit> = None;
    #[inline]
    fn answer(tracer: &Tracer, rays: &RayBatch, i: usize) -> Option<Hit> {
        let (o, d) = (rays.origins[i], rays.directions[i]);
        tracer.trace_closest(o, d, rays.t_max[i], rays.depth[i])
    }
    fn offer(
        accelerator: &dyn Accelerator,
        tracer: &Tracer,
        rays: &RayBatch,
        from: usize,
        out: &mut [Option<Hit>],
    ) -> Offer {
        accelerator.closest_from(tracer, rays, from, out)
    }
}

impl Tracer {
    /// Every ray's answer to `Q`, into `out` (cleared first), in the
    /// batch's order. Pieces of a large batch are traced in parallel.
    ///
    /// With an accelerator attached, it answers the batch when it takes
    /// it; while it is busy, this worker answers a piece of it on the CPU
    /// and offers the rest again, so the CPU's threads trace beside the
    /// device instead of waiting for it. Both answer every ray alike, so
    /// who answered which piece changes no answer.
    pub fn trace_batch<Q: Query>(&self, rays: &RayBatch, out: &mut Vec<Q::Answer>) {
        out.clear();
        out.resize(rays.len(), Q::Answer::default());
        let mut from = 0;
        if let Some(accelerator) = self.accelerator() {
            while from < rays.len() {
                match Q::offer(accelerator, self, rays, from, &mut out[from..]) {
                    Offer::Answered => return,
                    Offer::Busy => {
                        let end = (from + PIECE).min(rays.len());
                        self.trace_piece::<Q>(rays, from, &mut out[from..end]);
                        accelerator.answered_on_cpu(end - from);
                        from = end;
                    }
                    Offer::Failed => {
                        accelerator.answered_on_cpu(rays.len() - from);
                        break;
                    }
                }
            }
        }
        let out = &mut out[from..];
        if out.len() <= PIECE {
            self.trace_piece::<Q>(rays, from, out);
        } else {
            out.par_chunks_mut(PIECE)
                .enumerate()
                .for_each(|(k, out)| self.trace_piece::<Q>(rays, from + k * PIECE, out));
        }
    }

    /// The answers to `Q` of rays `first..first + out.len()`, one after
    /// the other on this thread.
    fn trace_piece<Q: Query>(&self, rays: &RayBatch, first: usize, out: &mut [Q::Answer]) {
        for (i, o) in (first..).zip(out.iter_mut()) {
            *o = if rays.is_blocked(i) {
                Q::BLOCKED
            } else {
                Q::answer(self, rays, i)
            };
        }
    }

    /// Per ray of `rays`, whether anything is hit in (0, t_max] (a blocked
    /// ray: true), into `out`.
    pub fn occluded_batch(&self, rays: &RayBatch, out: &mut Vec<bool>) {
        self.trace_batch::<Occlusion>(rays, out);
    }
}

/// Casts every receiver's rays as occlusion queries in batches, `chunk`
/// receivers to a batch, the batches in parallel: `emit(r, state, batch)`
/// pushes receiver r's rays (and may note in its state what it decided), `consume(r, state, directions, occluded)`
/// reads them back with their answers, in the order pushed (blocked rays
/// answer occluded); `states[r]` is receiver r's. `progress` is told the
/// receivers done.
pub fn for_each_receiver<S: Send>(
    tracer: &Tracer,
    states: &mut [S],
    chunk: usize,
    emit: impl Fn(usize, &mut S, &mut RayBatch) + Sync,
    consume: impl Fn(usize, &mut S, &[Vec3], &[bool]) + Sync,
    progress: &(dyn Fn(u64) + Sync),
) {
    for_each_receiver_query::<Occlusion, S>(tracer, states, chunk, emit, consume, progress);
}

/// [`for_each_receiver`] for any [`Query`] (closest hits: [`Closest`]).
/// Each worker keeps its batch and answers between chunks.
pub fn for_each_receiver_query<Q: Query, S: Send>(
    tracer: &Tracer,
    states: &mut [S],
    chunk: usize,
    emit: impl Fn(usize, &mut S, &mut RayBatch) + Sync,
    consume: impl Fn(usize, &mut S, &[Vec3], &[Q::Answer]) + Sync,
    progress: &(dyn Fn(u64) + Sync),
) {
    let chunk = chunk.max(1);
    // On a device a batch costs a round trip whatever its size: batches
    // of many receivers keep it busy (the answers do not depend on it).
    let chunk = match tracer.accelerator() {
        Some(_) => chunk.max(ACCELERATED_RECEIVERS),
        None => chunk,
    };
    states.par_chunks_mut(chunk).enumerate().for_each_init(
        || (RayBatch::new(), Vec::new(), Vec::new()),
        |(batch, ends, answers), (c, states)| {
            batch.clear();
            ends.clear();
            for (k, s) in states.iter_mut().enumerate() {
                emit(c * chunk + k, s, batch);
                ends.push(batch.len());
            }
            tracer.trace_batch::<Q>(batch, answers);
            let mut start = 0;
            for (k, (s, &end)) in states.iter_mut().zip(ends.iter()).enumerate() {
                consume(
                    c * chunk + k,
                    s,
                    &batch.directions[start..end],
                    &answers[start..end],
                );
                start = end;
            }
            progress(states.len() as u64);
        },
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3A;

    /// A unit quad in the plane z = h, centred on the z axis.
    fn quad(h: f32) -> Vec<[Vec3A; 3]> {
        let p = |x: f32, y: f32| Vec3A::new(x, y, h);
        vec![
            [p(-0.5, -0.5), p(0.5, -0.5), p(0.5, 0.5)],
            [p(-0.5, -0.5), p(0.5, 0.5), p(-0.5, 0.5)],
        ]
    }

    #[test]
    fn a_batch_answers_what_the_geometry_says() {
        // From (x, 0.13, 0) straight up to a quad at z = 0.2 over |x| < 0.5:
        // occluded exactly where |x| < 0.5 and t_max >= 0.2.
        let tracer = Tracer::new(&quad(0.2));
        let mut rays = RayBatch::new();
        let mut expected = Vec::new();
        for k in 0..10_000 {
            let x = -1.0 + 2.0 * (k as f32 + 0.5) / 10_000.0;
            let t_max = if k % 3 == 0 { 0.1 } else { 1.0 };
            rays.push(Vec3::new(x, 0.13, 0.0), Vec3::Z, t_max);
            expected.push(x.abs() < 0.5 && t_max > 0.2);
        }
        rays.push_blocked(-Vec3::Z);
        expected.push(true);
        rays.push(Vec3::ZERO, Vec3::Z, f32::NAN);
        expected.push(false);
        let mut out = Vec::new();
        tracer.occluded_batch(&rays, &mut out);
        assert_eq!(out, expected);
        assert!(rays.is_blocked(10_000) && !rays.is_blocked(0));
    }

    #[test]
    fn receivers_read_their_own_rays_back_in_order() {
        let tracer = Tracer::new(&quad(0.2));
        // Receiver r casts r % 5 rays: up (hit), down-blocked, sideways
        // (miss), in turn; its state counts what it read back.
        let n = 1000;
        let mut states = vec![(0u32, 0u32, 0u32); n];
        let kinds = [Vec3::Z, -Vec3::Z, Vec3::X];
        for chunk in [1, 7, 64, 5000] {
            states.iter_mut().for_each(|s| *s = (0, 0, 0));
            for_each_receiver(
                &tracer,
                &mut states,
                chunk,
                |r, _, batch| {
                    for i in 0..r % 5 {
                        let d = kinds[i % 3];
                        if d.z < 0.0 {
                            batch.push_blocked(d);
                        } else {
                            batch.push(Vec3::new(0.0, 0.1, 0.0), d, 1.0);
                        }
                    }
                },
                |r, s, dirs, hits| {
                    assert_eq!(dirs.len(), r % 5);
                    for (i, (d, &hit)) in dirs.iter().zip(hits).enumerate() {
                        assert_eq!(*d, kinds[i % 3]);
                        assert_eq!(hit, i % 3 != 2, "receiver {r} ray {i}");
                        s.0 += 1;
                        s.1 += hit as u32;
                    }
                    s.2 = r as u32;
                },
                &|_| {},
            );
            for (r, s) in states.iter().enumerate() {
                let rays = (r % 5) as u32;
                let misses = (0..rays).filter(|i| i % 3 == 2).count() as u32;
                assert_eq!(*s, (rays, rays - misses, r as u32), "chunk {chunk}");
            }
        }
    }
}
