//! Semi-Lagrangian advection of the face velocities (Stam 1999): each face takes the velocity
//! found by tracing its position back through the flow for one step. Unconditionally stable;
//! first order in time with a single Euler backtrace, second order in the trace with the
//! midpoint rule used here, and dissipative through the trilinear interpolation (the
//! Taylor–Green test measures how much).

use crate::grid::MacGrid;

/// Advects the velocity by itself over `h` seconds; `scratch` receives the old velocities
/// (kept between calls so a step allocates nothing after the first).
pub fn advect_velocity(grid: &mut MacGrid, h: f64, scratch: &mut Option<MacGrid>) {
    let old = match scratch {
        Some(s) if s.domain == grid.domain => {
            for a in 0..3 {
                s.vel[a].copy_from_slice(&grid.vel[a]);
            }
            s
        }
        _ => scratch.insert(grid.clone()),
    };
    let dom = grid.domain.clone();
    for a in 0..3 {
        let d = dom.face_dims(a);
        for k in 0..d[2] {
            for j in 0..d[1] {
                for i in 0..d[0] {
                    let x = dom.face_position(a, [i, j, k]);
                    // Midpoint backtrace: x_mid = x − ½h u(x), x_back = x − h u(x_mid).
                    let u0 = old.velocity_at(x);
                    let mid = [0, 1, 2].map(|b| x[b] - 0.5 * h * u0[b]);
                    let um = old.velocity_at(mid);
                    let back = [0, 1, 2].map(|b| x[b] - h * um[b]);
                    grid.vel[a][dom.face(a, i, j, k)] = old.sample(a, back);
                }
            }
        }
    }
    grid.apply_boundaries();
}
