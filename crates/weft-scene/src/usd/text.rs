//! The `.usda` text of a [`UsdaScene`]: the layer header, each prim's topology and time
//! samples, and the three layers of a clip set (a frame's clip, the manifest, the root).
//! Values are `f32` already (rounded when the samples were added); here they are only
//! written, with the shortest text that reads back to the same `f32`.

use std::collections::BTreeMap;
use std::fmt;

use super::{ClipSet, Prim, PrimKind, UsdaScene, VolumeField, VolumeFiles, bounds};

/// Comma-separated items on one line, each formatted by `item`.
fn list<T>(
    f: &mut fmt::Formatter<'_>,
    items: impl IntoIterator<Item = T>,
    mut item: impl FnMut(&mut fmt::Formatter<'_>, T) -> fmt::Result,
) -> fmt::Result {
    f.write_str("[")?;
    for (k, x) in items.into_iter().enumerate() {
        if k > 0 {
            f.write_str(", ")?;
        }
        item(f, x)?;
    }
    f.write_str("]")
}

/// `INDENT DECL.timeSamples = { frame: value, … }`, one sample a line, each value written by
/// `item`.
fn time_samples<'a, T: 'a>(
    f: &mut fmt::Formatter<'_>,
    indent: &str,
    decl: &str,
    samples: impl IntoIterator<Item = (&'a i64, &'a T)>,
    mut item: impl FnMut(&mut fmt::Formatter<'_>, &T) -> fmt::Result,
) -> fmt::Result {
    writeln!(f, "{indent}{decl}.timeSamples = {{")?;
    for (frame, value) in samples {
        write!(f, "{indent}    {frame}: ")?;
        item(f, value)?;
        writeln!(f, ",")?;
    }
    writeln!(f, "{indent}}}")
}

fn point(f: &mut fmt::Formatter<'_>, p: &[f32; 3]) -> fmt::Result {
    // `{}` on f32 is the shortest text that reads back to the same f32.
    write!(f, "({}, {}, {})", p[0], p[1], p[2])
}

pub(super) fn points_list(f: &mut fmt::Formatter<'_>, points: &[[f32; 3]]) -> fmt::Result {
    list(f, points, point)
}

/// Bounds padded by `pad`, as a USD `extent` value; `[]` for no points.
fn extent_list(f: &mut fmt::Formatter<'_>, bounds: Option<[[f32; 3]; 2]>, pad: f32) -> fmt::Result {
    let Some([lo, hi]) = bounds else {
        return f.write_str("[]");
    };
    let lo = lo.map(|c| c - pad);
    let hi = hi.map(|c| c + pad);
    list(f, [&lo, &hi], point)
}

impl Prim {
    /// What the extent adds around the points: half the widest strand (0 for a mesh).
    fn extent_pad(&self) -> f32 {
        match &self.kind {
            PrimKind::Curves {
                widths: Some(w), ..
            } => w.iter().copied().reduce(f32::max).unwrap_or(0.0) * 0.5,
            _ => 0.0,
        }
    }

    /// A mesh's or curves' definition up to its points: the `def` line, the opening brace and
    /// the topology (nothing for a volume, which [`Prim::fmt_volume`] writes whole).
    fn fmt_topology(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        const I: &str = "        ";
        match &self.kind {
            PrimKind::Mesh { triangles } => {
                writeln!(f, "    def Mesh \"{}\"", self.name)?;
                writeln!(f, "    {{")?;
                writeln!(f, "{I}uniform bool doubleSided = 1")?;
                write!(f, "{I}int[] faceVertexCounts = ")?;
                list(f, triangles, |f, _| f.write_str("3"))?;
                write!(f, "\n{I}int[] faceVertexIndices = ")?;
                list(f, triangles.iter().flatten(), |f, i| write!(f, "{i}"))?;
                writeln!(f)?;
                writeln!(f, "{I}uniform token subdivisionScheme = \"none\"")?;
            }
            PrimKind::Curves { counts, widths } => {
                writeln!(f, "    def BasisCurves \"{}\"", self.name)?;
                writeln!(f, "    {{")?;
                writeln!(f, "{I}uniform token type = \"linear\"")?;
                write!(f, "{I}int[] curveVertexCounts = ")?;
                list(f, counts, |f, c| write!(f, "{c}"))?;
                writeln!(f)?;
                if let Some(w) = widths {
                    write!(f, "{I}float[] widths = ")?;
                    list(f, w, |f, x| write!(f, "{x}"))?;
                    let interpolation = if w.len() == 1 { "constant" } else { "vertex" };
                    writeln!(f, " (\n{I}    interpolation = \"{interpolation}\"\n{I})")?;
                }
            }
            PrimKind::Volume { .. } => {}
        }
        Ok(())
    }

    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        const I: &str = "        ";
        if let PrimKind::Volume { fields, files } = &self.kind {
            return self.fmt_volume(f, fields, files);
        }
        self.fmt_topology(f)?;
        let pad = self.extent_pad();
        if self.samples.is_empty() {
            write!(f, "{I}float3[] extent = ")?;
            extent_list(f, bounds(&self.rest), pad)?;
            write!(f, "\n{I}point3f[] points = ")?;
            points_list(f, &self.rest)?;
            writeln!(f)?;
        } else {
            time_samples(f, I, "float3[] extent", &self.samples, |f, p| {
                extent_list(f, p.bounds, pad)
            })?;
            time_samples(f, I, "point3f[] points", &self.samples, |f, p| {
                f.write_str(&p.text)
            })?;
        }
        if !self.velocities.is_empty() {
            time_samples(f, I, "vector3f[] velocities", &self.velocities, |f, v| {
                f.write_str(&v.text)
            })?;
        }
        writeln!(f, "    }}")
    }

    fn fmt_volume(
        &self,
        f: &mut fmt::Formatter<'_>,
        fields: &[VolumeField],
        files: &VolumeFiles,
    ) -> fmt::Result {
        const I: &str = "        ";
        writeln!(f, "    def Volume \"{}\"", self.name)?;
        writeln!(f, "    {{")?;
        let extents: BTreeMap<i64, [[f32; 3]; 2]> = files
            .iter()
            .filter_map(|(k, (_, e))| Some((*k, (*e)?)))
            .collect();
        if !extents.is_empty() {
            time_samples(f, I, "float3[] extent", &extents, |f, e| list(f, e, point))?;
        }
        for field in fields {
            writeln!(
                f,
                "{I}rel field:{} = </World/{}/{}>",
                field.name, self.name, field.name
            )?;
        }
        for field in fields {
            writeln!(f)?;
            writeln!(f, "{I}def OpenVDBAsset \"{}\"", field.name)?;
            writeln!(f, "{I}{{")?;
            writeln!(f, "{I}    token fieldDataType = \"{}\"", field.data_type)?;
            writeln!(f, "{I}    token fieldName = \"{}\"", field.name)?;
            time_samples(
                f,
                &format!("{I}    "),
                "asset filePath",
                files,
                |f, (p, _)| write!(f, "@{p}@"),
            )?;
            if let Some(role) = field.role {
                writeln!(f, "{I}    token vectorDataRoleHint = \"{role}\"")?;
            }
            writeln!(f, "{I}}}")?;
        }
        writeln!(f, "    }}")
    }
}

/// A root layer's header: the stage's metadata (its frame range when there is one), then a
/// blank line.
fn layer_header(f: &mut fmt::Formatter<'_>, fps: f64, range: Option<(i64, i64)>) -> fmt::Result {
    writeln!(f, "#usda 1.0")?;
    writeln!(f, "(")?;
    writeln!(f, "    defaultPrim = \"World\"")?;
    writeln!(f, "    doc = \"Written by Weft\"")?;
    if let Some((first, last)) = range {
        writeln!(f, "    endTimeCode = {last}")?;
        writeln!(f, "    framesPerSecond = {fps}")?;
        writeln!(f, "    metersPerUnit = 1")?;
        writeln!(f, "    startTimeCode = {first}")?;
    } else {
        writeln!(f, "    framesPerSecond = {fps}")?;
        writeln!(f, "    metersPerUnit = 1")?;
    }
    writeln!(f, "    timeCodesPerSecond = {fps}")?;
    writeln!(f, "    upAxis = \"Y\"")?;
    writeln!(f, ")")?;
    writeln!(f)
}

impl fmt::Display for UsdaScene {
    /// The scene as `.usda` text.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        layer_header(f, self.fps, self.frame_range())?;
        writeln!(f, "def Xform \"World\"")?;
        writeln!(f, "{{")?;
        for (k, prim) in self.prims.iter().enumerate() {
            if k > 0 {
                writeln!(f)?;
            }
            prim.fmt(f)?;
        }
        writeln!(f, "}}")
    }
}

/// One frame's clip layer, for [`UsdaScene::write_clip`].
pub(super) struct ClipLayer<'a> {
    pub(super) scene: &'a UsdaScene,
    pub(super) frame: i64,
}

/// The meshes and curves: the prims whose values clips hold.
fn point_based(scene: &UsdaScene) -> impl Iterator<Item = &Prim> {
    scene
        .prims
        .iter()
        .filter(|p| !matches!(p.kind, PrimKind::Volume { .. }))
}

impl fmt::Display for ClipLayer<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        const I: &str = "        ";
        let frame = self.frame;
        writeln!(f, "#usda 1.0")?;
        writeln!(f)?;
        writeln!(f, "over \"World\"")?;
        writeln!(f, "{{")?;
        let mut first = true;
        for prim in point_based(self.scene) {
            let sample = prim.samples.get_key_value(&frame);
            let velocity = prim.velocities.get_key_value(&frame);
            if sample.is_none() && velocity.is_none() {
                continue;
            }
            if !first {
                writeln!(f)?;
            }
            first = false;
            writeln!(f, "    over \"{}\"", prim.name)?;
            writeln!(f, "    {{")?;
            if sample.is_some() {
                let pad = prim.extent_pad();
                time_samples(f, I, "float3[] extent", sample, |f, p| {
                    extent_list(f, p.bounds, pad)
                })?;
                time_samples(f, I, "point3f[] points", sample, |f, p| {
                    f.write_str(&p.text)
                })?;
            }
            if velocity.is_some() {
                time_samples(f, I, "vector3f[] velocities", velocity, |f, v| {
                    f.write_str(&v.text)
                })?;
            }
            writeln!(f, "    }}")?;
        }
        writeln!(f, "}}")
    }
}

/// The clips' manifest, for [`UsdaScene::write_manifest`].
pub(super) struct Manifest<'a>(pub(super) &'a UsdaScene);

impl fmt::Display for Manifest<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        const I: &str = "        ";
        writeln!(f, "#usda 1.0")?;
        writeln!(f)?;
        writeln!(f, "over \"World\"")?;
        writeln!(f, "{{")?;
        for (k, prim) in point_based(self.0).enumerate() {
            if k > 0 {
                writeln!(f)?;
            }
            writeln!(f, "    over \"{}\"", prim.name)?;
            writeln!(f, "    {{")?;
            writeln!(f, "{I}float3[] extent")?;
            writeln!(f, "{I}point3f[] points")?;
            writeln!(f, "{I}vector3f[] velocities")?;
            writeln!(f, "    }}")?;
        }
        writeln!(f, "}}")
    }
}

/// A clip set's root layer, for [`UsdaScene::write_clip_root`].
pub(super) struct ClipRoot<'a> {
    pub(super) scene: &'a UsdaScene,
    pub(super) clips: &'a ClipSet,
}

impl fmt::Display for ClipRoot<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (scene, clips) = (self.scene, self.clips);
        if clips.frames.is_empty() {
            return fmt::Display::fmt(scene, f);
        }
        // The range: the clips' frames and the volumes' files.
        let mut frames: Vec<i64> = clips.frames.keys().copied().collect();
        for p in &scene.prims {
            if let PrimKind::Volume { files, .. } = &p.kind {
                frames.extend(files.keys());
            }
        }
        let range = frames.iter().min().zip(frames.iter().max());
        layer_header(f, scene.fps, range.map(|(a, b)| (*a, *b)))?;
        const D: &str = "            ";
        writeln!(f, "def Xform \"World\" (")?;
        writeln!(f, "    clips = {{")?;
        writeln!(f, "        dictionary default = {{")?;
        // Clip k is active from its frame on, and maps each stage time to itself.
        write!(f, "{D}double2[] active = ")?;
        list(f, clips.frames.keys().enumerate(), |f, (k, t)| {
            write!(f, "({t}, {k})")
        })?;
        write!(f, "\n{D}asset[] assetPaths = ")?;
        list(f, clips.frames.values(), |f, p| write!(f, "@{p}@"))?;
        writeln!(f)?;
        writeln!(f, "{D}asset manifestAssetPath = @{}@", clips.manifest)?;
        writeln!(f, "{D}string primPath = \"/World\"")?;
        write!(f, "{D}double2[] times = ")?;
        list(f, clips.frames.keys(), |f, t| write!(f, "({t}, {t})"))?;
        writeln!(f)?;
        writeln!(f, "        }}")?;
        writeln!(f, "    }}")?;
        writeln!(f, ")")?;
        writeln!(f, "{{")?;
        for (k, prim) in scene.prims.iter().enumerate() {
            if k > 0 {
                writeln!(f)?;
            }
            if let PrimKind::Volume { .. } = prim.kind {
                prim.fmt(f)?;
            } else {
                prim.fmt_topology(f)?;
                writeln!(f, "    }}")?;
            }
        }
        writeln!(f, "}}")
    }
}
