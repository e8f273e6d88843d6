//! USD ASCII (`.usda`) export of animated meshes and curves.
//!
//! This file builds the scene and checks what is added; `usd/text.rs` writes it. The tests
//! below check the text against the format line by line.
//!
//! A [`UsdaScene`] collects prims (triangle meshes as `Mesh`, strands as linear
//! `BasisCurves`) with fixed topology, then per-frame positions as time samples, and writes one
//! `.usda` layer: a `World` Xform (the default prim) holding every prim, with `points` (and
//! `extent`) time-sampled. Or it writes the same stage as a clip set: a root layer with the
//! topology, one value clip a frame with that frame's samples, and their manifest
//! ([`UsdaScene::write_clip_root`]), which a run writes frame by frame without rewriting
//! the earlier frames. The stage is Y-up, in metres, with `timeCodesPerSecond` set to the
//! frame rate, so frame numbers are time codes.
//!
//! ```
//! use weft_scene::{Mesh, usd::UsdaScene};
//! let mesh = Mesh {
//!     positions: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
//!     triangles: vec![[0, 1, 2]],
//! };
//! let mut scene = UsdaScene::new(24.0)?;
//! let cloth = scene.add_mesh("cloth", &mesh)?;
//! scene.set_points(cloth, 0, &mesh.positions)?;
//! let text = scene.to_string();
//! assert!(text.starts_with("#usda 1.0"));
//! # Ok::<(), weft_scene::usd::UsdError>(())
//! ```
//!
//! USD stores `point3f` and `float` values in single precision, so positions and widths are
//! rounded to `f32` and written with the shortest text that reads back to that exact `f32`:
//! full precision for the attribute type, without meaningless extra digits.

use std::collections::BTreeMap;
use std::fmt;
use std::io::{self, Write};

use crate::geometry::{Curves, Mesh};

mod text;

use text::{ClipLayer, ClipRoot, Manifest, points_list};

/// Why a prim or a frame could not be added to a [`UsdaScene`].
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum UsdError {
    /// The frame rate is not a finite positive number.
    #[error("frames per second must be a finite positive number, got {0}")]
    InvalidFps(f64),
    /// A prim's topology is inconsistent (index out of range, bad curve offsets, short curve).
    #[error("prim `{prim}`: {message}")]
    BadTopology {
        /// Prim name (sanitized).
        prim: String,
        /// What is wrong.
        message: String,
    },
    /// Curve widths have neither one value nor one per vertex, or a width is not finite.
    #[error("prim `{prim}`: {message}")]
    BadWidths {
        /// Prim name (sanitized).
        prim: String,
        /// What is wrong.
        message: String,
    },
    /// Positions for a frame do not have one entry per vertex of the prim.
    #[error("prim `{prim}`, frame {frame}: expected {expected} positions, got {found}")]
    PointCount {
        /// Prim name (sanitized).
        prim: String,
        /// The frame.
        frame: i64,
        /// Vertex count of the prim.
        expected: usize,
        /// Positions given.
        found: usize,
    },
    /// A position is NaN, infinite, or too large for single precision.
    #[error(
        "prim `{prim}`{}: vertex {vertex} has a coordinate that is not finite in single \
         precision",
        frame.map(|f| format!(", frame {f}")).unwrap_or_default()
    )]
    NonFinite {
        /// Prim name (sanitized).
        prim: String,
        /// The frame (`None` for the rest positions given when adding the prim).
        frame: Option<i64>,
        /// Index of the vertex.
        vertex: usize,
    },
    /// [`UsdaScene::add_frame`] got a number of position sets different from the prim count.
    #[error("frame {frame}: expected positions for {expected} prims, got {found}")]
    PrimCount {
        /// The frame.
        frame: i64,
        /// Number of prims in the scene.
        expected: usize,
        /// Position sets given.
        found: usize,
    },
    /// A [`PrimId`] that does not belong to this scene.
    #[error("no prim with id {0} in this scene")]
    UnknownPrim(usize),
}

/// Handle to a prim of a [`UsdaScene`], in the order prims were added.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct PrimId(pub usize);

#[derive(Debug, Clone)]
enum PrimKind {
    Mesh {
        triangles: Vec<[u32; 3]>,
    },
    Curves {
        counts: Vec<u32>,
        widths: Option<Vec<f32>>,
    },
    /// A `Volume` of OpenVDB fields: per frame the file and the volume's extent.
    Volume {
        fields: Vec<VolumeField>,
        files: VolumeFiles,
    },
}

/// A volume's file and extent per frame.
type VolumeFiles = BTreeMap<i64, (String, Option<[[f32; 3]; 2]>)>;

/// One field of a volume prim: the grid's name in the VDB files and its data type.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct VolumeField {
    /// The grid's name (the `OpenVDBAsset`'s `fieldName`, and the prim's name).
    pub name: String,
    /// `float` for scalar grids, `float3` for vector grids (UsdVol's `fieldDataType`).
    pub data_type: &'static str,
    /// For vectors, how they transform (`Vector` for velocities; UsdVol's
    /// `vectorDataRoleHint`).
    pub role: Option<&'static str>,
}

#[derive(Debug, Clone)]
struct Prim {
    name: String,
    kind: PrimKind,
    /// Positions given when the prim was added; written as the default value when the prim has
    /// no time samples.
    rest: Vec<[f32; 3]>,
    samples: BTreeMap<i64, Sample>,
    /// Velocities [m/s] per frame (`velocities`, which renderers use for motion blur).
    velocities: BTreeMap<i64, Sample>,
}

/// One frame's values of a point attribute, formatted once when they are set: a single layer
/// written again after each frame copies the earlier frames' text instead of formatting their
/// floats again (cloth_hang, 576 points: 5.6 ms of 7 a frame at 24 frames, ten times that at
/// 240). Copying still grows with the frames, which is why a run writes a clip set instead
/// ([`UsdaScene::write_clip_root`]).
#[derive(Debug, Clone)]
struct Sample {
    /// The values' bounds (for `extent`), `None` when there are none.
    bounds: Option<[[f32; 3]; 2]>,
    /// The values as a `.usda` list, `[(x, y, z), …]`.
    text: String,
}

impl Sample {
    fn new(values: &[[f32; 3]]) -> Sample {
        let bounds = bounds(values);
        let mut text = String::with_capacity(values.len() * 36 + 2);
        // Writing to a String cannot fail.
        let _ = fmt::write(&mut text, format_args!("{}", PointsList(values)));
        Sample { bounds, text }
    }
}

/// The smallest and largest coordinates of `values`, `None` when there are none.
fn bounds(values: &[[f32; 3]]) -> Option<[[f32; 3]; 2]> {
    let first = values.first()?;
    let (mut lo, mut hi) = (*first, *first);
    for p in values {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    Some([lo, hi])
}

/// A point list's `.usda` text, for [`Sample::new`].
struct PointsList<'a>(&'a [[f32; 3]]);

impl fmt::Display for PointsList<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        points_list(f, self.0)
    }
}

/// An animated USD scene being built, written as `.usda` text.
///
/// Add prims with [`add_mesh`](Self::add_mesh) / [`add_curves`](Self::add_curves), then
/// positions per frame with [`add_frame`](Self::add_frame) (all prims) or
/// [`set_points`](Self::set_points) (one prim); format with `to_string()` (via [`fmt::Display`])
/// or [`write`](Self::write).
#[derive(Debug, Clone)]
pub struct UsdaScene {
    fps: f64,
    prims: Vec<Prim>,
}

/// Turns `name` into a valid USD identifier (`[A-Za-z_][A-Za-z0-9_]*`): every other character
/// becomes `_`, a leading digit gets a `_` prefix, and an empty name becomes `_`.
///
/// `"my cloth-1"` gives `"my_cloth_1"`, `"1abc"` gives `"_1abc"`.
pub fn sanitize_identifier(name: &str) -> String {
    let mut out: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect();
    if out.is_empty() || out.starts_with(|c: char| c.is_ascii_digit()) {
        out.insert(0, '_');
    }
    out
}

/// Converts positions to `f32`, reporting the first vertex that is not finite in `f32`.
fn to_f32_points(positions: &[[f64; 3]]) -> Result<Vec<[f32; 3]>, usize> {
    positions
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let q = p.map(|c| c as f32);
            if q.iter().all(|c| c.is_finite()) {
                Ok(q)
            } else {
                Err(i)
            }
        })
        .collect()
}

impl UsdaScene {
    /// An empty scene at `fps` frames (time codes) per second.
    ///
    /// # Errors
    ///
    /// [`UsdError::InvalidFps`] unless `fps` is finite and positive.
    pub fn new(fps: f64) -> Result<Self, UsdError> {
        if !(fps.is_finite() && fps > 0.0) {
            return Err(UsdError::InvalidFps(fps));
        }
        Ok(UsdaScene {
            fps,
            prims: Vec::new(),
        })
    }

    /// Frames (time codes) per second.
    pub fn fps(&self) -> f64 {
        self.fps
    }

    /// Number of prims.
    pub fn prim_count(&self) -> usize {
        self.prims.len()
    }

    /// The name a prim is written with: `name` sanitized by [`sanitize_identifier`], with a
    /// `_2`, `_3`… suffix when another prim already has it.
    pub fn prim_name(&self, id: PrimId) -> Option<&str> {
        self.prims.get(id.0).map(|p| p.name.as_str())
    }

    /// First and last frame with a time sample, over all prims.
    pub fn frame_range(&self) -> Option<(i64, i64)> {
        let keys = |p: &Prim| -> Vec<i64> {
            let mut k: Vec<i64> = p.samples.keys().copied().collect();
            if let PrimKind::Volume { files, .. } = &p.kind {
                k.extend(files.keys());
            }
            k
        };
        let first = self
            .prims
            .iter()
            .filter_map(|p| keys(p).into_iter().min())
            .min()?;
        let last = self
            .prims
            .iter()
            .filter_map(|p| keys(p).into_iter().max())
            .max()?;
        Some((first, last))
    }

    fn unique_name(&self, name: &str) -> String {
        let base = sanitize_identifier(name);
        let taken = |n: &str| self.prims.iter().any(|p| p.name == n);
        if !taken(&base) {
            return base;
        }
        (2..)
            .map(|k| format!("{base}_{k}"))
            .find(|n| !taken(n))
            .unwrap_or(base)
    }

    /// Adds a triangle mesh prim: topology from `mesh.triangles` (three vertices per face,
    /// counter-clockwise = USD's default right-handed orientation), and `mesh.positions` as the
    /// points written when no frame is added for it.
    ///
    /// # Errors
    ///
    /// [`UsdError::BadTopology`] for a triangle index out of range, [`UsdError::NonFinite`] for
    /// a bad position.
    pub fn add_mesh(&mut self, name: &str, mesh: &Mesh) -> Result<PrimId, UsdError> {
        let name = self.unique_name(name);
        let n = mesh.positions.len();
        if let Some((k, t)) = mesh
            .triangles
            .iter()
            .enumerate()
            .find(|(_, t)| t.iter().any(|&i| i as usize >= n))
        {
            return Err(UsdError::BadTopology {
                prim: name,
                message: format!(
                    "triangle {k} {t:?} refers to a vertex out of range ({n} vertices)"
                ),
            });
        }
        let rest = to_f32_points(&mesh.positions).map_err(|vertex| UsdError::NonFinite {
            prim: name.clone(),
            frame: None,
            vertex,
        })?;
        self.prims.push(Prim {
            name,
            kind: PrimKind::Mesh {
                triangles: mesh.triangles.clone(),
            },
            rest,
            samples: BTreeMap::new(),
            velocities: BTreeMap::new(),
        });
        Ok(PrimId(self.prims.len() - 1))
    }

    /// Adds a linear `BasisCurves` prim: one curve per curve of `curves` (each needs at least two
    /// vertices), `curves.positions` as the points written when no frame is added for it, and
    /// optional widths [m]: one value (constant) or one per vertex.
    ///
    /// # Errors
    ///
    /// [`UsdError::BadTopology`] for invalid offsets or a curve with fewer than two vertices,
    /// [`UsdError::BadWidths`] for widths of the wrong length or non-finite/negative widths,
    /// [`UsdError::NonFinite`] for a bad position.
    pub fn add_curves(
        &mut self,
        name: &str,
        curves: &Curves,
        widths: Option<&[f64]>,
    ) -> Result<PrimId, UsdError> {
        let name = self.unique_name(name);
        let bad_topology = |message: String| UsdError::BadTopology {
            prim: name.clone(),
            message,
        };
        crate::obj::check_offsets(curves).map_err(bad_topology)?;
        let counts: Vec<u32> = curves.offsets.windows(2).map(|p| p[1] - p[0]).collect();
        if let Some(k) = counts.iter().position(|&c| c < 2) {
            return Err(bad_topology(format!(
                "curve {k} has {} vertices; a linear curve needs at least 2",
                counts[k]
            )));
        }
        let n = curves.positions.len();
        let widths = match widths {
            None => None,
            Some(w) => {
                if w.len() != 1 && w.len() != n {
                    return Err(UsdError::BadWidths {
                        prim: name,
                        message: format!(
                            "{} widths given; expected 1 (constant) or {n} (one per vertex)",
                            w.len()
                        ),
                    });
                }
                let w32: Vec<f32> = w.iter().map(|&x| x as f32).collect();
                if let Some(k) = w32.iter().position(|x| !(x.is_finite() && *x >= 0.0)) {
                    return Err(UsdError::BadWidths {
                        prim: name,
                        message: format!("width {k} is {}; widths must be finite and >= 0", w[k]),
                    });
                }
                Some(w32)
            }
        };
        let rest = to_f32_points(&curves.positions).map_err(|vertex| UsdError::NonFinite {
            prim: name.clone(),
            frame: None,
            vertex,
        })?;
        self.prims.push(Prim {
            name,
            kind: PrimKind::Curves { counts, widths },
            rest,
            samples: BTreeMap::new(),
            velocities: BTreeMap::new(),
        });
        Ok(PrimId(self.prims.len() - 1))
    }

    fn checked_points(
        &self,
        prim: usize,
        frame: i64,
        positions: &[[f64; 3]],
    ) -> Result<Vec<[f32; 3]>, UsdError> {
        let p = self.prims.get(prim).ok_or(UsdError::UnknownPrim(prim))?;
        if positions.len() != p.rest.len() {
            return Err(UsdError::PointCount {
                prim: p.name.clone(),
                frame,
                expected: p.rest.len(),
                found: positions.len(),
            });
        }
        to_f32_points(positions).map_err(|vertex| UsdError::NonFinite {
            prim: p.name.clone(),
            frame: Some(frame),
            vertex,
        })
    }

    /// Sets the positions of one prim at `frame` (replacing an earlier sample at that frame).
    ///
    /// # Errors
    ///
    /// [`UsdError::UnknownPrim`], [`UsdError::PointCount`] when the vertex count differs from
    /// the prim's, [`UsdError::NonFinite`]; the scene is unchanged on error.
    pub fn set_points(
        &mut self,
        prim: PrimId,
        frame: i64,
        positions: &[[f64; 3]],
    ) -> Result<(), UsdError> {
        let points = self.checked_points(prim.0, frame, positions)?;
        self.prims[prim.0]
            .samples
            .insert(frame, Sample::new(&points));
        Ok(())
    }

    /// Sets the velocities [m/s] of one mesh or curves prim at `frame`, one per vertex
    /// (written as `velocities`, which renderers read for motion blur).
    ///
    /// # Errors
    ///
    /// [`UsdError::UnknownPrim`] (or a volume prim), [`UsdError::PointCount`],
    /// [`UsdError::NonFinite`]; the scene is unchanged on error.
    pub fn set_velocities(
        &mut self,
        prim: PrimId,
        frame: i64,
        velocities: &[[f64; 3]],
    ) -> Result<(), UsdError> {
        if matches!(
            self.prims.get(prim.0).map(|p| &p.kind),
            Some(PrimKind::Volume { .. })
        ) {
            return Err(UsdError::UnknownPrim(prim.0));
        }
        let v = self.checked_points(prim.0, frame, velocities)?;
        self.prims[prim.0].velocities.insert(frame, Sample::new(&v));
        Ok(())
    }

    /// Adds a `Volume` prim whose fields are OpenVDB grids (`OpenVDBAsset` children, one per
    /// field), with files given per frame by [`set_volume_file`](Self::set_volume_file).
    ///
    /// # Errors
    ///
    /// [`UsdError::BadTopology`] when there are no fields or two share a name.
    pub fn add_volume(&mut self, name: &str, fields: &[VolumeField]) -> Result<PrimId, UsdError> {
        let name = self.unique_name(name);
        let mut seen = std::collections::BTreeSet::new();
        for f in fields {
            let id = sanitize_identifier(&f.name);
            if id != f.name || !seen.insert(id) {
                return Err(UsdError::BadTopology {
                    prim: name,
                    message: format!(
                        "field name {:?} is used twice or is not an identifier ([A-Za-z_][A-Za-z0-9_]*)",
                        f.name
                    ),
                });
            }
        }
        if fields.is_empty() {
            return Err(UsdError::BadTopology {
                prim: name,
                message: "a volume needs at least one field".into(),
            });
        }
        self.prims.push(Prim {
            name,
            kind: PrimKind::Volume {
                fields: fields.to_vec(),
                files: BTreeMap::new(),
            },
            rest: Vec::new(),
            samples: BTreeMap::new(),
            velocities: BTreeMap::new(),
        });
        Ok(PrimId(self.prims.len() - 1))
    }

    /// Sets the VDB file of a volume prim at `frame` (an asset path, best relative to the
    /// `.usda` file) and, when known, the volume's extent there (its box's minimum and maximum
    /// corners; a frame without one writes no extent sample).
    ///
    /// # Errors
    ///
    /// [`UsdError::UnknownPrim`] for a prim that is not a volume, [`UsdError::BadTopology`] for
    /// a path USD cannot hold (`@`, a line break) or a non-finite extent.
    pub fn set_volume_file(
        &mut self,
        prim: PrimId,
        frame: i64,
        path: &str,
        extent: Option<[[f64; 3]; 2]>,
    ) -> Result<(), UsdError> {
        let Some(Prim {
            name,
            kind: PrimKind::Volume { files, .. },
            ..
        }) = self.prims.get_mut(prim.0)
        else {
            return Err(UsdError::UnknownPrim(prim.0));
        };
        if path.is_empty() || path.contains(['@', '\n', '\r']) {
            return Err(UsdError::BadTopology {
                prim: name.clone(),
                message: format!("asset path {path:?} is empty or holds '@' or a line break"),
            });
        }
        let e32 = extent.map(|e| e.map(|c| c.map(|x| x as f32)));
        if !e32.iter().flatten().flatten().all(|x| x.is_finite()) {
            return Err(UsdError::BadTopology {
                prim: name.clone(),
                message: format!("extent {extent:?} is not finite"),
            });
        }
        files.insert(frame, (path.to_string(), e32));
        Ok(())
    }

    /// Adds a frame: `positions[k]` are the positions of the k-th mesh or curves prim added
    /// (volumes are skipped), at `frame` (replacing earlier samples at that frame).
    ///
    /// # Errors
    ///
    /// [`UsdError::PrimCount`] unless there is one position set per prim, and the errors of
    /// [`set_points`](Self::set_points); the scene is unchanged on error.
    pub fn add_frame(&mut self, frame: i64, positions: &[&[[f64; 3]]]) -> Result<(), UsdError> {
        let point_based: Vec<usize> = (0..self.prims.len())
            .filter(|&k| !matches!(self.prims[k].kind, PrimKind::Volume { .. }))
            .collect();
        if positions.len() != point_based.len() {
            return Err(UsdError::PrimCount {
                frame,
                expected: point_based.len(),
                found: positions.len(),
            });
        }
        let all = point_based
            .iter()
            .zip(positions)
            .map(|(&k, p)| self.checked_points(k, frame, p))
            .collect::<Result<Vec<_>, _>>()?;
        for (&k, points) in point_based.iter().zip(all) {
            self.prims[k].samples.insert(frame, Sample::new(&points));
        }
        Ok(())
    }

    /// Writes the scene as `.usda` text.
    ///
    /// # Errors
    ///
    /// I/O errors from `w`.
    pub fn write(&self, w: &mut impl Write) -> io::Result<()> {
        write!(w, "{self}")
    }

    /// Writes the meshes' and curves' samples at `frame` (`extent`, `points`, `velocities`)
    /// as a value clip: a layer of `over`s under `/World` holding that one frame, which the
    /// root of [`write_clip_root`](Self::write_clip_root) lists. Prims without a sample at
    /// `frame` are left out.
    ///
    /// # Errors
    ///
    /// I/O errors from `w`.
    pub fn write_clip(&self, frame: i64, w: &mut impl Write) -> io::Result<()> {
        write!(w, "{}", ClipLayer { scene: self, frame })
    }

    /// Writes the clips' manifest: the attributes the clips give values to (`extent`,
    /// `points` and `velocities` of every mesh and curves prim), declared without values.
    ///
    /// # Errors
    ///
    /// I/O errors from `w`.
    pub fn write_manifest(&self, w: &mut impl Write) -> io::Result<()> {
        write!(w, "{}", Manifest(self))
    }

    /// Writes the root layer of a clip set: the stage's metadata, the prims' topology (no
    /// points: those come from the clips, one layer a frame) with the clips' metadata on
    /// `/World`, and the volumes whole (their per-frame file paths are small). With no frame
    /// in `clips`, the meshes and curves keep their points as in [`write`](Self::write).
    ///
    /// Why clips: a root holding every frame is rewritten whole after each frame, so a run's
    /// writing grows as the square of its frames; a frame's clip is written once, and the
    /// root grows by a line's worth of metadata a frame. USD resolves the clips at composition, interpolating across
    /// them (checked with usd-core: `tests/fields.rs`).
    ///
    /// # Errors
    ///
    /// I/O errors from `w`.
    pub fn write_clip_root(&self, clips: &ClipSet, w: &mut impl Write) -> io::Result<()> {
        write!(w, "{}", ClipRoot { scene: self, clips })
    }

    /// Drops the meshes' and curves' samples, once their clips are written: a run then holds
    /// one frame at a time, however long.
    pub fn forget_point_samples(&mut self) {
        for p in &mut self.prims {
            p.samples.clear();
            p.velocities.clear();
        }
    }
}

/// Where the root of a clip set ([`UsdaScene::write_clip_root`]) finds its layers: asset
/// paths relative to the root layer, written between `@`s (so without `@` in them).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ClipSet {
    /// The manifest ([`UsdaScene::write_manifest`]).
    pub manifest: String,
    /// Per frame, the clip holding its samples ([`UsdaScene::write_clip`]).
    pub frames: BTreeMap<i64, String>,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad(z: f64) -> Mesh {
        Mesh {
            positions: vec![[0.0, 0.0, z], [1.0, 0.0, z], [1.0, 1.0, z], [0.0, 1.0, z]],
            triangles: vec![[0, 1, 2], [0, 2, 3]],
        }
    }

    fn strands() -> Curves {
        Curves {
            positions: vec![
                [0.0, 0.0, 0.0],
                [0.0, 0.5, 0.0],
                [0.0, 1.0, 0.0],
                [1.0, 0.0, 0.0],
                [1.0, 1.0, 0.0],
            ],
            offsets: vec![0, 3, 5],
        }
    }

    fn balanced(text: &str, open: char, close: char) -> bool {
        let mut depth = 0_i64;
        for c in text.chars() {
            if c == open {
                depth += 1;
            } else if c == close {
                depth -= 1;
                if depth < 0 {
                    return false;
                }
            }
        }
        depth == 0
    }

    /// The clip set holds what the single layer holds: each frame's samples in its own clip
    /// (the same lines), the topology and the clips' metadata in the root, and every
    /// clip-varying attribute declared in the manifest. (usd-core reads a run's clip set in
    /// `tests/fields.rs`.)
    #[test]
    fn a_clip_set_splits_the_frames_out_of_the_root() {
        let mut scene = UsdaScene::new(30.0).expect("fps");
        let cloth = quad(0.0);
        let hair = strands();
        scene.add_mesh("cloth", &cloth).expect("mesh");
        scene
            .add_curves("hair", &hair, Some(&[0.002]))
            .expect("curves");
        let mut clips = ClipSet {
            manifest: "./s.clips/manifest.usda".into(),
            frames: BTreeMap::new(),
        };
        let single = |scene: &UsdaScene| scene.to_string();
        let text = |write: &dyn Fn(&mut Vec<u8>) -> io::Result<()>| {
            let mut b = Vec::new();
            write(&mut b).expect("write");
            String::from_utf8(b).expect("utf-8")
        };
        for frame in [3, 4] {
            let z = -0.1 * f64::from(frame as i32);
            scene
                .add_frame(frame, &[&quad(z).positions, &hair.positions])
                .expect("frame");
            let whole = single(&scene);
            let clip = text(&|w| scene.write_clip(frame, w));
            assert!(
                clip.starts_with("#usda 1.0\n\nover \"World\"\n{\n    over \"cloth\"\n"),
                "{clip}"
            );
            // The clip's sample lines are the single layer's for this frame.
            let line = |t: &str, from: &str| {
                t.lines()
                    .skip_while(|l| !l.contains(from))
                    .find(|l| l.trim_start().starts_with(&format!("{frame}: ")))
                    .map(str::to_string)
            };
            for attr in ["extent", "points"] {
                let needle = format!("{attr}.timeSamples");
                assert!(line(&clip, &needle).is_some(), "{clip}");
                assert_eq!(line(&clip, &needle), line(&whole, &needle));
            }
            assert_eq!(clip.matches(".timeSamples").count(), 4, "{clip}");
            for (open, close) in [('{', '}'), ('(', ')'), ('[', ']')] {
                assert!(
                    balanced(&clip, open, close),
                    "{open}{close} unbalanced in {clip}"
                );
            }
            clips
                .frames
                .insert(frame, format!("./s.clips/s.{frame:04}.usda"));
            scene.forget_point_samples();
        }
        let root = text(&|w| scene.write_clip_root(&clips, w));
        for needle in [
            "startTimeCode = 3",
            "endTimeCode = 4",
            "def Xform \"World\" (\n    clips = {\n        dictionary default = {\n",
            "double2[] active = [(3, 0), (4, 1)]\n",
            "asset[] assetPaths = [@./s.clips/s.0003.usda@, @./s.clips/s.0004.usda@]\n",
            "asset manifestAssetPath = @./s.clips/manifest.usda@\n",
            "string primPath = \"/World\"\n",
            "double2[] times = [(3, 3), (4, 4)]\n",
            "int[] faceVertexIndices = [0, 1, 2, 0, 2, 3]\n",
            "float[] widths = [0.002]",
        ] {
            assert!(root.contains(needle), "missing {needle:?} in\n{root}");
        }
        assert!(!root.contains("points"), "{root}");
        for (open, close) in [('{', '}'), ('(', ')'), ('[', ']')] {
            assert!(
                balanced(&root, open, close),
                "{open}{close} unbalanced in {root}"
            );
        }
        let manifest = text(&|w| scene.write_manifest(w));
        assert_eq!(
            manifest.matches("point3f[] points\n").count(),
            2,
            "{manifest}"
        );
        assert_eq!(manifest.matches("vector3f[] velocities\n").count(), 2);
        // Without a clip the root is the single layer.
        assert_eq!(
            text(&|w| scene.write_clip_root(&ClipSet::default(), w)),
            single(&scene)
        );
    }

    #[test]
    fn two_frame_scene() {
        let mut scene = UsdaScene::new(30.0).expect("fps");
        let cloth = quad(0.0);
        let hair = strands();
        let c = scene.add_mesh("my cloth-1", &cloth).expect("mesh");
        let h = scene
            .add_curves("hair", &hair, Some(&[0.002]))
            .expect("curves");
        assert_eq!(scene.prim_name(c), Some("my_cloth_1"));
        assert_eq!(scene.prim_name(h), Some("hair"));

        let moved_cloth = quad(-0.1);
        let moved_hair: Vec<[f64; 3]> = hair
            .positions
            .iter()
            .map(|p| [p[0] + 0.1, p[1], p[2]])
            .collect();
        scene
            .add_frame(0, &[&cloth.positions, &hair.positions])
            .expect("frame 0");
        scene
            .add_frame(1, &[&moved_cloth.positions, &moved_hair])
            .expect("frame 1");
        assert_eq!(scene.frame_range(), Some((0, 1)));

        let text = scene.to_string();
        assert!(text.starts_with("#usda 1.0\n(\n"), "{text}");
        for needle in [
            "defaultPrim = \"World\"",
            "startTimeCode = 0",
            "endTimeCode = 1",
            "timeCodesPerSecond = 30",
            "upAxis = \"Y\"",
            "metersPerUnit = 1",
            "def Xform \"World\"",
            "def Mesh \"my_cloth_1\"",
            "int[] faceVertexCounts = [3, 3]\n",
            "int[] faceVertexIndices = [0, 1, 2, 0, 2, 3]\n",
            "uniform token subdivisionScheme = \"none\"",
            "point3f[] points.timeSamples = {",
            "0: [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)],",
            "1: [(0, 0, -0.1), (1, 0, -0.1), (1, 1, -0.1), (0, 1, -0.1)],",
            "def BasisCurves \"hair\"",
            "uniform token type = \"linear\"",
            "int[] curveVertexCounts = [3, 2]\n",
            "float[] widths = [0.002]",
            "interpolation = \"constant\"",
            "0: [(0, 0, 0), (0, 0.5, 0), (0, 1, 0), (1, 0, 0), (1, 1, 0)],",
            "1: [(0.1, 0, 0), (0.1, 0.5, 0), (0.1, 1, 0), (1.1, 0, 0), (1.1, 1, 0)],",
            // Extent of the hair at frame 0, padded by half the width.
            "0: [(-0.001, -0.001, -0.001), (1.001, 1.001, 0.001)],",
        ] {
            assert!(text.contains(needle), "missing {needle:?} in\n{text}");
        }
        assert_eq!(text.matches("points.timeSamples").count(), 2);
        assert_eq!(text.matches("def ").count(), 3);
        for (open, close) in [('{', '}'), ('(', ')'), ('[', ']')] {
            assert!(balanced(&text, open, close), "{open}{close} unbalanced");
        }

        let mut bytes = Vec::new();
        scene.write(&mut bytes).expect("write");
        assert_eq!(bytes, text.as_bytes());
    }

    #[test]
    fn points_use_full_single_precision() {
        let mut scene = UsdaScene::new(24.0).expect("fps");
        let mut m = quad(0.0);
        m.positions[1] = [0.1, 1.0 / 3.0, 16_777_217.0];
        scene.add_mesh("m", &m).expect("mesh");
        let text = scene.to_string();
        // No time samples: the rest positions are the default value, with no time range.
        assert!(text.contains("(0.1, 0.33333334, 16777216)"), "{text}");
        assert!(!text.contains("startTimeCode"));
        assert!(text.contains("float3[] extent = [(0, 0, 0), (1, 1, 16777216)]"));
        let parsed: f32 = "0.33333334".parse().expect("f32");
        assert_eq!(parsed, (1.0_f64 / 3.0) as f32);
    }

    #[test]
    fn names_are_sanitized_and_unique() {
        assert_eq!(sanitize_identifier("my cloth-1"), "my_cloth_1");
        assert_eq!(sanitize_identifier("1abc"), "_1abc");
        assert_eq!(sanitize_identifier(""), "_");
        assert_eq!(sanitize_identifier("héllo.obj"), "h_llo_obj");
        assert_eq!(sanitize_identifier("_ok_9"), "_ok_9");
        let mut scene = UsdaScene::new(24.0).expect("fps");
        let m = quad(0.0);
        let names: Vec<String> = ["cloth", "cloth", "cloth!", "cloth", "cloth_2"]
            .iter()
            .map(|n| {
                let id = scene.add_mesh(n, &m).expect("mesh");
                scene.prim_name(id).expect("name").to_owned()
            })
            .collect();
        assert_eq!(
            names,
            ["cloth", "cloth_2", "cloth_", "cloth_3", "cloth_2_2"]
        );
    }

    #[test]
    fn bad_input_is_an_error() {
        assert_eq!(UsdaScene::new(0.0).err(), Some(UsdError::InvalidFps(0.0)));
        assert!(UsdaScene::new(f64::NAN).is_err());
        let mut scene = UsdaScene::new(24.0).expect("fps");
        let mut m = quad(0.0);
        m.triangles.push([0, 1, 4]);
        assert!(matches!(
            scene.add_mesh("m", &m),
            Err(UsdError::BadTopology { .. })
        ));
        let mut m = quad(0.0);
        m.positions[2][1] = f64::NAN;
        assert!(matches!(
            scene.add_mesh("m", &m),
            Err(UsdError::NonFinite {
                vertex: 2,
                frame: None,
                ..
            })
        ));
        let mut c = strands();
        c.offsets = vec![0, 4, 5];
        assert!(matches!(
            scene.add_curves("h", &c, None),
            Err(UsdError::BadTopology { .. })
        ));
        c.offsets = vec![0, 3, 6];
        assert!(scene.add_curves("h", &c, None).is_err());
        assert!(matches!(
            scene.add_curves("h", &strands(), Some(&[0.1, 0.2])),
            Err(UsdError::BadWidths { .. })
        ));
        assert!(scene.add_curves("h", &strands(), Some(&[-1.0])).is_err());
        assert_eq!(scene.prim_count(), 0);

        let id = scene.add_mesh("m", &quad(0.0)).expect("mesh");
        let h = scene
            .add_curves("h", &strands(), Some(&[0.1; 5]))
            .expect("curves");
        let q = quad(0.0);
        let s = strands();
        assert!(matches!(
            scene.add_frame(0, &[&q.positions]),
            Err(UsdError::PrimCount {
                expected: 2,
                found: 1,
                ..
            })
        ));
        assert!(matches!(
            scene.add_frame(3, &[&q.positions, &q.positions]),
            Err(UsdError::PointCount {
                frame: 3,
                expected: 5,
                found: 4,
                ..
            })
        ));
        let mut far = s.positions.clone();
        far[4][0] = 1e39; // finite in f64, not in f32
        let err = scene
            .add_frame(2, &[&q.positions, &far])
            .expect_err("too large");
        assert_eq!(
            err.to_string(),
            "prim `h`, frame 2: vertex 4 has a coordinate that is not finite in single precision"
        );
        // Nothing was added by the failed frames.
        assert_eq!(scene.frame_range(), None);
        assert!(scene.set_points(PrimId(7), 0, &q.positions).is_err());
        scene.set_points(id, 5, &q.positions).expect("one prim");
        assert_eq!(scene.frame_range(), Some((5, 5)));
        let text = scene.to_string();
        // Per-vertex widths; the curves prim without samples keeps its rest points.
        assert!(text.contains("interpolation = \"vertex\""), "{text}");
        assert_eq!(text.matches("points.timeSamples").count(), 1);
        assert_eq!(text.matches("point3f[] points = ").count(), 1);
        let _ = h;
    }
}
