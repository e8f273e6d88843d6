//! Wavefront OBJ input and output for meshes and curves.
//!
//! [`read_obj`] loads a triangle mesh (polygons are fan-triangulated); [`write_obj_mesh`]
//! and [`write_obj_curves`] write meshes (`v` and `f` records) and curves (`l` polyline
//! records). Positions are written with Rust's shortest round-trip formatting of `f64` and read
//! back as `f64`, so writing then reading a mesh gives back the same positions bit for bit, in
//! the same vertex order.
//!
//! The reader is a small strict parser rather than the `tobj` crate: `tobj` (as configured here,
//! without its `use_f64` feature) parses coordinates as `f32`, and it renumbers vertices in
//! first-use order per object, dropping unused vertices and duplicating vertices shared across
//! objects, which would break both exact round trips and per-vertex data keyed by index.
//! Vertex indices in OBJ are global to the file, so all objects and groups of a file form one
//! [`Mesh`] whose vertices are exactly the file's `v` records, in order.
//!
//! Records other than `v` and `f` (`vt`, `vn`, `o`, `g`, `s`, `usemtl`, `mtllib`, `l`, `p`…) are
//! ignored when reading.

use std::io::{self, Write};
use std::path::{Path, PathBuf};

use crate::geometry::{Curves, Mesh};

/// Why an OBJ file could not be read.
#[derive(Debug, thiserror::Error)]
pub enum ObjError {
    /// The file could not be opened or read.
    #[error("cannot read OBJ file {}: {source}", .path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: io::Error,
    },
    /// A record is malformed: a bad number, a face with fewer than three vertices, a zero index…
    #[error("OBJ file {}, line {line}: {message}", .path.display())]
    Parse {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// A vertex coordinate is NaN or infinite.
    #[error(
        "OBJ file {}, line {line}: vertex coordinate is not a finite number ({value})",
        .path.display()
    )]
    NonFinite {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// The offending value.
        value: f64,
    },
    /// A face refers to a vertex the file does not define.
    #[error(
        "OBJ file {}, line {line}: face refers to vertex {index}, but the file defines {count} \
         vertices (indices are 1-based; negative indices count back from the last vertex)",
        .path.display()
    )]
    IndexOutOfRange {
        /// The file.
        path: PathBuf,
        /// 1-based line number of the face.
        line: usize,
        /// The index as written in the file.
        index: i64,
        /// Number of vertices in the file.
        count: usize,
    },
    /// The file has no faces, so it is not a triangle mesh.
    #[error(
        "OBJ file {} has no triangles: a mesh needs at least one `f` record with 3 or more \
         vertices",
        .path.display()
    )]
    NoTriangles {
        /// The file.
        path: PathBuf,
    },
}

/// Reads a triangle mesh from an OBJ file.
///
/// Every `v` record becomes a vertex, in file order (a fourth `w` coordinate divides the first
/// three; vertex colours after `x y z` are ignored). Every `f` record with `n >= 3` vertices
/// becomes `n - 2` triangles fanned from its first vertex; `v/vt/vn` index forms and negative
/// (relative) indices are accepted. All objects and groups are merged into one mesh.
///
/// # Errors
///
/// [`ObjError`] when the file cannot be read, a record is malformed, a coordinate is not
/// finite, a face index is out of range, or there are no triangles. Messages name the file and
/// the line.
pub fn read_obj(path: &Path) -> Result<Mesh, ObjError> {
    let bytes = std::fs::read(path).map_err(|source| ObjError::Io {
        path: path.to_owned(),
        source,
    })?;
    parse_obj(&String::from_utf8_lossy(&bytes), path)
}

/// A face index as read, kept with its line for error messages until all vertices are known
/// (OBJ allows faces to refer to vertices defined later in the file).
#[derive(Clone, Copy)]
struct PendingIndex {
    resolved: i64,
    written: i64,
    line: usize,
}

fn parse_obj(text: &str, path: &Path) -> Result<Mesh, ObjError> {
    let parse_err = |line: usize, message: String| ObjError::Parse {
        path: path.to_owned(),
        line,
        message,
    };
    let mut positions: Vec<[f64; 3]> = Vec::new();
    // Triangle corners, three per triangle.
    let mut corners: Vec<PendingIndex> = Vec::new();
    let mut face: Vec<PendingIndex> = Vec::new();

    for (k, raw) in text.lines().enumerate() {
        let line = k + 1;
        let content = raw.split('#').next().unwrap_or("");
        let mut words = content.split_whitespace();
        match words.next() {
            Some("v") => {
                let mut vals = [0.0_f64; 4];
                let mut n = 0;
                for word in words {
                    if n < 4 {
                        vals[n] = word.parse::<f64>().map_err(|_| {
                            parse_err(line, format!("`v` record has a bad number `{word}`"))
                        })?;
                    }
                    n += 1;
                }
                if n < 3 {
                    return Err(parse_err(
                        line,
                        format!("`v` record needs 3 coordinates, found {n}"),
                    ));
                }
                let mut p = [vals[0], vals[1], vals[2]];
                if n == 4 {
                    let w = vals[3];
                    if w == 0.0 || !w.is_finite() {
                        return Err(parse_err(
                            line,
                            format!("`v` record has an invalid weight w = {w}"),
                        ));
                    }
                    p = p.map(|c| c / w);
                }
                if let Some(&value) = p.iter().find(|c| !c.is_finite()) {
                    return Err(ObjError::NonFinite {
                        path: path.to_owned(),
                        line,
                        value,
                    });
                }
                positions.push(p);
            }
            Some("f") => {
                face.clear();
                for word in words {
                    let v = word.split('/').next().unwrap_or("");
                    let written: i64 = v.parse().map_err(|_| {
                        parse_err(line, format!("`f` record has a bad vertex index `{word}`"))
                    })?;
                    let resolved = match written {
                        0 => {
                            return Err(parse_err(
                                line,
                                "`f` record has vertex index 0 (OBJ indices start at 1)".into(),
                            ));
                        }
                        i if i > 0 => i - 1,
                        // Relative: -1 is the last vertex defined so far.
                        // (saturating: a hugely negative index is reported out of range)
                        i => (positions.len() as i64).saturating_add(i),
                    };
                    face.push(PendingIndex {
                        resolved,
                        written,
                        line,
                    });
                }
                if face.len() < 3 {
                    return Err(parse_err(
                        line,
                        format!("`f` record needs at least 3 vertices, found {}", face.len()),
                    ));
                }
                for j in 1..face.len() - 1 {
                    corners.extend([face[0], face[j], face[j + 1]]);
                }
            }
            _ => {}
        }
    }

    if corners.is_empty() {
        return Err(ObjError::NoTriangles {
            path: path.to_owned(),
        });
    }
    let count = positions.len();
    if count > u32::MAX as usize {
        return Err(parse_err(
            text.lines().count(),
            format!(
                "too many vertices ({count}); at most {} are supported",
                u32::MAX
            ),
        ));
    }
    let mut triangles = Vec::with_capacity(corners.len() / 3);
    for tri in corners.chunks_exact(3) {
        let mut t = [0_u32; 3];
        for (slot, c) in t.iter_mut().zip(tri) {
            if c.resolved < 0 || c.resolved >= count as i64 {
                return Err(ObjError::IndexOutOfRange {
                    path: path.to_owned(),
                    line: c.line,
                    index: c.written,
                    count,
                });
            }
            *slot = c.resolved as u32;
        }
        triangles.push(t);
    }
    Ok(Mesh {
        positions,
        triangles,
    })
}

fn invalid(message: String) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidData, message)
}

fn write_vertices(positions: &[[f64; 3]], w: &mut impl Write) -> io::Result<()> {
    for (i, p) in positions.iter().enumerate() {
        if p.iter().any(|c| !c.is_finite()) {
            return Err(invalid(format!(
                "vertex {i} has a non-finite coordinate {p:?}; OBJ cannot carry it"
            )));
        }
        // `{}` on f64 is the shortest representation that parses back to the same bits.
        writeln!(w, "v {} {} {}", p[0], p[1], p[2])?;
    }
    Ok(())
}

/// Writes a mesh as OBJ: one `v` record per vertex and one `f` record per triangle (1-based).
///
/// Coordinates use shortest round-trip formatting, so [`read_obj`] returns exactly the same
/// positions and triangles.
///
/// # Errors
///
/// I/O errors from `w`, and [`io::ErrorKind::InvalidData`] (before anything is written for a
/// bad index, or at the offending vertex) when a coordinate is not finite or a triangle index is
/// out of range.
pub fn write_obj_mesh(mesh: &Mesh, w: &mut impl Write) -> io::Result<()> {
    let n = mesh.positions.len();
    if let Some((k, t)) = mesh
        .triangles
        .iter()
        .enumerate()
        .find(|(_, t)| t.iter().any(|&i| i as usize >= n))
    {
        return Err(invalid(format!(
            "triangle {k} {t:?} refers to a vertex out of range (the mesh has {n} vertices)"
        )));
    }
    writeln!(
        w,
        "# weft mesh: {n} vertices, {} triangles",
        mesh.triangles.len()
    )?;
    write_vertices(&mesh.positions, w)?;
    for t in &mesh.triangles {
        writeln!(w, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1)?;
    }
    Ok(())
}

/// Writes curves as OBJ: one `v` record per vertex and one `l` polyline record per curve
/// (1-based indices).
///
/// A curve with a single vertex is written as a `p` (point) record, since an `l` record needs
/// two vertices; a curve with no vertex writes nothing.
///
/// # Errors
///
/// I/O errors from `w`, and [`io::ErrorKind::InvalidData`] when `offsets` is not a valid
/// partition of the vertices (it must start at 0, not decrease, and end at the vertex count) or
/// a coordinate is not finite.
pub fn write_obj_curves(curves: &Curves, w: &mut impl Write) -> io::Result<()> {
    check_offsets(curves).map_err(invalid)?;
    writeln!(
        w,
        "# weft curves: {} vertices, {} curves",
        curves.positions.len(),
        curves.len()
    )?;
    write_vertices(&curves.positions, w)?;
    for pair in curves.offsets.windows(2) {
        let (a, b) = (pair[0], pair[1]);
        match b - a {
            0 => continue,
            1 => write!(w, "p")?,
            _ => write!(w, "l")?,
        }
        for i in a..b {
            write!(w, " {}", u64::from(i) + 1)?;
        }
        writeln!(w)?;
    }
    Ok(())
}

/// Checks that `offsets` partitions the curve vertices; the message says what is wrong.
pub(crate) fn check_offsets(curves: &Curves) -> Result<(), String> {
    let n = curves.positions.len();
    match curves.offsets.first() {
        None if n == 0 => return Ok(()),
        None => return Err(format!("curves have {n} vertices but no offsets")),
        Some(0) => {}
        Some(&o) => return Err(format!("curve offsets must start at 0, found {o}")),
    }
    if let Some(k) = curves.offsets.windows(2).position(|p| p[1] < p[0]) {
        return Err(format!(
            "curve offsets decrease at curve {k} ({} then {})",
            curves.offsets[k],
            curves.offsets[k + 1]
        ));
    }
    let last = curves.offsets.last().copied().unwrap_or(0) as usize;
    if last != n {
        return Err(format!(
            "the last curve offset is {last} but there are {n} vertices"
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write_tmp(text: &str) -> tempfile::NamedTempFile {
        let mut f = tempfile::Builder::new()
            .suffix(".obj")
            .tempfile()
            .expect("temp file");
        f.write_all(text.as_bytes()).expect("write");
        f.flush().expect("flush");
        f
    }

    #[test]
    fn mesh_round_trips_bit_exactly() {
        // Values that do not survive f32, tiny and huge magnitudes, -0, and an unused vertex
        // plus triangles that use vertices out of first-use order.
        let mesh = Mesh {
            positions: vec![
                [0.1, 0.2, 0.30000000000000004],
                [-0.0, 1e-300, 1.7976931348623157e308],
                [std::f64::consts::PI, -std::f64::consts::E, 5e-324],
                [(0.1 + 0.2) * 12345.6789, -1.0 / 3.0, 2.0_f64.sqrt()],
                [9.0, 9.0, 9.0],
            ],
            triangles: vec![[2, 0, 1], [3, 2, 1], [0, 3, 1]],
        };
        let mut file = tempfile::Builder::new()
            .suffix(".obj")
            .tempfile()
            .expect("temp file");
        write_obj_mesh(&mesh, &mut file).expect("write");
        file.flush().expect("flush");
        let back = read_obj(file.path()).expect("read back");
        assert_eq!(back.triangles, mesh.triangles);
        assert_eq!(back.positions.len(), mesh.positions.len());
        for (a, b) in back.positions.iter().zip(&mesh.positions) {
            for k in 0..3 {
                assert_eq!(a[k].to_bits(), b[k].to_bits(), "{a:?} vs {b:?}");
            }
        }
    }

    #[test]
    fn polygons_are_fanned_and_objects_merged() {
        let f = write_tmp(
            "# quad and a triangle in two objects\n\
             o first\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
             f 1/1/1 2/2/2 3/3/3 4/4/4\n\
             o second\nv 2 0 0 1\nv 4 2 0 2\n\
             f -2 -1 3 # relative indices\n\
             g pentagon\nf 1 2 3 4 5\n",
        );
        let m = read_obj(f.path()).expect("read");
        assert_eq!(m.positions.len(), 6);
        assert_eq!(m.positions[5], [2.0, 1.0, 0.0]); // w = 2 divides
        assert_eq!(
            m.triangles,
            vec![
                [0, 1, 2],
                [0, 2, 3],
                [4, 5, 2],
                [0, 1, 2],
                [0, 2, 3],
                [0, 3, 4]
            ]
        );
    }

    #[test]
    fn forward_references_are_allowed() {
        let f = write_tmp("f 1 2 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\n");
        let m = read_obj(f.path()).expect("read");
        assert_eq!(m.triangles, vec![[0, 1, 2]]);
    }

    #[test]
    fn malformed_files_are_errors_not_panics() {
        let cases: &[(&str, &str)] = &[
            ("", "no triangles"),
            ("v 0 0 0\nv 1 0 0\nl 1 2\n", "no triangles"),
            ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", "refers to vertex 4"),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -4\n",
                "refers to vertex -4",
            ),
            ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", "index 0"),
            ("v 0 0 0\nv 1 0 0\nf 1 2\n", "at least 3 vertices"),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n",
                "bad vertex index `x`",
            ),
            ("v 0 zero 0\n", "bad number `zero`"),
            ("v 0 0\n", "needs 3 coordinates"),
            (
                "v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
                "not a finite number",
            ),
            ("v 1e999 0 0\n", "not a finite number"),
            ("v 0 0 0 0\n", "invalid weight"),
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99999999999999999999\n",
                "bad vertex index",
            ),
            // The most negative relative index: out of range, not an overflow.
            (
                "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -9223372036854775808\n",
                "refers to vertex",
            ),
        ];
        for (text, expected) in cases {
            let f = write_tmp(text);
            let err = read_obj(f.path()).expect_err(text).to_string();
            assert!(err.contains(expected), "{text:?}: {err}");
            let name = f.path().display().to_string();
            assert!(err.contains(&name), "{err} should name {name}");
        }
        // Binary garbage.
        let f = write_tmp("\u{0}\u{1}\u{fffd}v\u{7}f");
        assert!(read_obj(f.path()).is_err());
        // Missing file.
        let err = read_obj(Path::new("/nonexistent/weft/none.obj")).expect_err("missing");
        assert!(
            err.to_string().contains("/nonexistent/weft/none.obj"),
            "{err}"
        );
    }

    #[test]
    fn error_reports_the_line() {
        let f = write_tmp("v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 1 2 3\nf 1 2 7\n");
        match read_obj(f.path()) {
            Err(ObjError::IndexOutOfRange {
                line, index, count, ..
            }) => assert_eq!((line, index, count), (6, 7, 3)),
            other => panic!("unexpected {other:?}"),
        }
    }

    #[test]
    fn writers_emit_one_based_records() {
        let mesh = Mesh {
            positions: vec![[0.0, 0.0, 0.0], [1.5, 0.0, 0.0], [0.0, 0.25, -2.0]],
            triangles: vec![[0, 1, 2]],
        };
        let mut out = Vec::new();
        write_obj_mesh(&mesh, &mut out).expect("write");
        let text = String::from_utf8(out).expect("utf8");
        let records: Vec<&str> = text.lines().filter(|l| !l.starts_with('#')).collect();
        assert_eq!(records, ["v 0 0 0", "v 1.5 0 0", "v 0 0.25 -2", "f 1 2 3"]);

        let curves = Curves {
            positions: vec![[0.0; 3], [0.0, 1.0, 0.0], [0.0, 2.0, 0.0], [1.0, 0.0, 0.0]],
            offsets: vec![0, 3, 3, 4],
        };
        let mut out = Vec::new();
        write_obj_curves(&curves, &mut out).expect("write");
        let text = String::from_utf8(out).expect("utf8");
        let records: Vec<&str> = text.lines().filter(|l| !l.starts_with('#')).collect();
        assert_eq!(
            records,
            ["v 0 0 0", "v 0 1 0", "v 0 2 0", "v 1 0 0", "l 1 2 3", "p 4"]
        );
    }

    #[test]
    fn writers_reject_bad_input() {
        let bad_index = Mesh {
            positions: vec![[0.0; 3]; 3],
            triangles: vec![[0, 1, 3]],
        };
        let mut out = Vec::new();
        let err = write_obj_mesh(&bad_index, &mut out).expect_err("bad index");
        assert_eq!(err.kind(), io::ErrorKind::InvalidData);
        assert!(out.is_empty());

        let nan = Mesh {
            positions: vec![[0.0, f64::NAN, 0.0]],
            triangles: vec![],
        };
        let err = write_obj_mesh(&nan, &mut Vec::new()).expect_err("nan");
        assert!(err.to_string().contains("vertex 0"), "{err}");

        for offsets in [vec![1, 2], vec![0, 2, 1, 2], vec![0, 1], vec![]] {
            let c = Curves {
                positions: vec![[0.0; 3]; 2],
                offsets: offsets.clone(),
            };
            let err = write_obj_curves(&c, &mut Vec::new()).expect_err("bad offsets");
            assert_eq!(err.kind(), io::ErrorKind::InvalidData, "{offsets:?}");
        }
        // No curves at all is fine.
        write_obj_curves(&Curves::default(), &mut Vec::new()).expect("empty");
    }
}
