//! A small software renderer for looking at results without a 3-D package.
//!
//! [`render`] draws meshes (z-buffered, flat two-sided Lambert shading, lit from the camera's
//! upper left) and curves (depth-tested one- or two-pixel lines) over a light grey gradient;
//! [`auto_camera`] frames given bounds from a three-quarter view; [`write_png`] saves the
//! [`Image`] atomically.
//!
//! Bad input never panics: vertices that are NaN or infinite, triangles with an index out of
//! range, degenerate triangles and geometry behind the camera are skipped or clipped, curves
//! with invalid offsets are skipped, and an unusable camera gives a background-only image.
//!
//! ```
//! use weft_scene::{Mesh, preview::{PreviewItem, auto_camera, render, scene_bounds}};
//! let mesh = Mesh {
//!     positions: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
//!     triangles: vec![[0, 1, 2]],
//! };
//! let items = [PreviewItem::Mesh(&mesh, [200, 120, 80])];
//! let bounds = scene_bounds(&items).unwrap_or(([0.0; 3], [0.0; 3]));
//! let image = render(&items, &auto_camera(bounds, 4.0 / 3.0), 320, 240);
//! assert_eq!(image.rgb.len(), 320 * 240 * 3);
//! ```

use std::io;
use std::path::PathBuf;

use crate::geometry::{Curves, Mesh};

/// Largest width or height [`render`] produces; larger requests are clamped to it.
pub const MAX_DIMENSION: u32 = 8192;

/// A pinhole camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Eye position [m].
    pub eye: [f64; 3],
    /// Point looked at [m].
    pub target: [f64; 3],
    /// Up direction (need not be orthogonal to the view direction).
    pub up: [f64; 3],
    /// Vertical field of view [degrees]; values outside 1–170 are clamped, non-finite ones
    /// replaced by 45.
    pub fov_y_degrees: f64,
}

/// An 8-bit RGB image, rows top to bottom.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Image {
    /// Width [pixels].
    pub width: u32,
    /// Height [pixels].
    pub height: u32,
    /// `width * height` RGB triples, row-major from the top-left pixel.
    pub rgb: Vec<u8>,
}

impl Image {
    /// The colour of pixel `(x, y)` (from the top left), or `None` outside the image.
    pub fn pixel(&self, x: u32, y: u32) -> Option<[u8; 3]> {
        if x >= self.width || y >= self.height {
            return None;
        }
        let i = (y as usize * self.width as usize + x as usize) * 3;
        let p = self.rgb.get(i..i + 3)?;
        Some([p[0], p[1], p[2]])
    }
}

/// Something to draw, with its base colour.
#[derive(Clone, Copy, Debug)]
pub enum PreviewItem<'a> {
    /// A triangle mesh, shaded.
    Mesh(&'a Mesh, [u8; 3]),
    /// Curves, drawn as lines.
    Curves(&'a Curves, [u8; 3]),
}

/// Why a PNG could not be written.
#[derive(Debug, thiserror::Error)]
pub enum PreviewError {
    /// Creating, writing or renaming the file failed.
    #[error("cannot write PNG {}: {source}", .path.display())]
    Io {
        /// The file being written (the temporary file or the destination).
        path: PathBuf,
        /// The underlying error.
        source: io::Error,
    },
    /// The PNG encoder failed.
    #[error("cannot encode PNG {}: {source}", .path.display())]
    Png {
        /// The destination.
        path: PathBuf,
        /// The encoder error.
        source: png::EncodingError,
    },
    /// The image cannot be saved (zero size, or pixel data of the wrong length), or the path
    /// does not name a file.
    #[error("cannot write PNG {}: {message}", .path.display())]
    Invalid {
        /// The destination.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
}

mod camera;
mod file;
mod raster;
#[cfg(test)]
mod tests;

pub use camera::{auto_camera, scene_bounds};
pub use file::{encode_png, write_png};
pub use raster::render;
