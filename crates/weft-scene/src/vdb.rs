//! OpenVDB (`.vdb`) export of dense fields on a regular grid.
//!
//! OpenVDB publishes no format specification apart from its source; this writer follows the
//! library's own serialization (OpenVDB 10–12, `io/Archive.cc`, `io/GridDescriptor.cc`,
//! `tree/RootNode.h`, `InternalNode.h`, `LeafNode.h`, `io/Compression.h`, `math/Maps.h`) and
//! writes file format version 224, which OpenVDB 8 and later read. It is checked against
//! OpenVDB itself by `tests/fields.rs` (Debian's `python3-openvdb` reads every grid back).
//!
//! A file is: the header (magic `0x56444220` as i64, format version, library version, a
//! "has grid offsets" byte, a 36-character UUID), the file's metadata, the grid count, and
//! per grid a descriptor (unique name, tree type such as `Tree_float_5_4_3`, instance parent,
//! then the byte offsets of the grid, of its leaf buffers and of its end) followed by the grid:
//! its compression flags, metadata, transform (`UniformScaleTranslateMap`: index (i, j, k)
//! maps to `origin + voxel_size · (i, j, k)`, so a cell-centred field puts `origin` at the
//! first cell's centre), the tree's topology and the leaves' values. The tree is OpenVDB's
//! standard 5-4-3 configuration: a root table of 4096³ internal nodes, 128³ internal nodes
//! below them, 8³ leaves; child and voxel offsets are `(x << 2L) + (y << L) + z` (z fastest),
//! and children are written in ascending offset order, root children in (x, y, z)
//! lexicographic order. Every voxel of the dense box is active; voxels of a boundary leaf
//! outside it are inactive with the background value (0). Values are `f32` (`float`,
//! `vec3s` grids), optionally zlib-compressed per node (OpenVDB's `COMPRESS_ZIP`: a signed
//! i64 byte count, negative for data stored raw, then the bytes).
//!
//! All integers are little-endian, as OpenVDB writes them on the platforms it supports.
//! Output is deterministic: the UUID is derived from the file's content.

/// The file format version written (OpenVDB's `OPENVDB_FILE_VERSION_MULTIPASS_IO`).
pub const FILE_VERSION: u32 = 224;
const MAGIC: i64 = 0x5644_4220;
/// Library version recorded in the header (informational; readers check the format version).
const LIBRARY_VERSION: (u32, u32) = (10, 0);
/// `io::COMPRESS_ZIP`.
const COMPRESS_ZIP: u32 = 0x1;
/// The per-node indicator `NO_MASK_AND_ALL_VALS`: every value of the node follows.
const ALL_VALUES: u8 = 6;

/// What the grid's values mean to a reader (OpenVDB's `GridClass`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GridClass {
    /// Any field (`"unknown"`).
    Unknown,
    /// A density-like field, zero outside (`"fog volume"`).
    FogVolume,
    /// A vector field whose components live on the faces of a voxel (`"staggered"`).
    Staggered,
}

impl GridClass {
    fn as_str(self) -> &'static str {
        match self {
            GridClass::Unknown => "unknown",
            GridClass::FogVolume => "fog volume",
            GridClass::Staggered => "staggered",
        }
    }
}

/// How a vector grid's values transform (OpenVDB's `VecType`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VectorType {
    /// Not transformed (`"invariant"`).
    Invariant,
    /// Transformed like displacements, without translation: velocities
    /// (`"contravariant relative"`).
    ContravariantRelative,
}

impl VectorType {
    fn as_str(self) -> &'static str {
        match self {
            VectorType::Invariant => "invariant",
            VectorType::ContravariantRelative => "contravariant relative",
        }
    }
}

/// A grid's values, one per voxel, x fastest: voxel (i, j, k) is entry
/// `i + nx · (j + ny · k)`.
#[derive(Clone, Debug, PartialEq)]
pub enum Values {
    /// A scalar field (`Tree_float_5_4_3`).
    Float(Vec<f32>),
    /// A vector field (`Tree_vec3s_5_4_3`).
    Vec3(Vec<[f32; 3]>),
}

impl Values {
    fn len(&self) -> usize {
        match self {
            Values::Float(v) => v.len(),
            Values::Vec3(v) => v.len(),
        }
    }
}

/// One dense field to write: voxels (0..nx, 0..ny, 0..nz) of index space, all active.
#[derive(Clone, Debug, PartialEq)]
pub struct DenseGrid {
    /// The grid's name (unique in a file).
    pub name: String,
    /// Its class.
    pub class: GridClass,
    /// For vector grids: how the vectors transform (ignored for scalar grids).
    pub vector_type: VectorType,
    /// Voxels per axis.
    pub dims: [usize; 3],
    /// Edge length of a voxel [m].
    pub voxel_size: f64,
    /// World position of voxel (0, 0, 0) [m] (its centre, for cell-centred data).
    pub origin: [f64; 3],
    /// The values.
    pub values: Values,
    /// Store the values as 16-bit half floats (OpenVDB's `_HalfFloat` grids: half the size,
    /// 11 significant bits, magnitudes up to 65504).
    pub half: bool,
}

/// How node values are stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Compression {
    /// Raw values.
    None,
    /// zlib per node (OpenVDB's `COMPRESS_ZIP`), at the fastest level.
    Zip,
}

/// Why grids could not be written.
#[derive(Debug, thiserror::Error)]
pub enum VdbError {
    /// A grid has no name, or two grids share one.
    #[error("grid name {0:?} is empty or used twice; every grid needs its own name")]
    Name(String),
    /// The values do not fill the grid's box.
    #[error("grid `{name}`: {found} values for {dims:?} voxels")]
    Size {
        /// The grid.
        name: String,
        /// Its voxels per axis.
        dims: [usize; 3],
        /// Values given.
        found: usize,
    },
    /// The grid has no voxels along an axis, or more than OpenVDB's 32-bit coordinates hold.
    #[error("grid `{name}`: {dims:?} voxels; each axis needs 1 to 2^31 − 1")]
    Dims {
        /// The grid.
        name: String,
        /// Its voxels per axis.
        dims: [usize; 3],
    },
    /// The voxel size or origin is not a finite positive size / finite position.
    #[error(
        "grid `{name}`: voxel size {voxel_size} m and origin {origin:?} m must be finite, the size > 0"
    )]
    Transform {
        /// The grid.
        name: String,
        /// The voxel size.
        voxel_size: f64,
        /// The origin.
        origin: [f64; 3],
    },
    /// A value is NaN or infinite (in single precision).
    #[error("grid `{name}`: the value of voxel {voxel:?} is not finite")]
    NonFinite {
        /// The grid.
        name: String,
        /// Index of the voxel.
        voxel: [usize; 3],
    },
    /// A value too large for a half-float grid.
    #[error(
        "grid `{name}`: the value of voxel {voxel:?} exceeds half precision's 65504; write it as float"
    )]
    HalfRange {
        /// The grid.
        name: String,
        /// Index of the voxel.
        voxel: [usize; 3],
    },
    /// A file being described is not a VDB file this module understands.
    #[error("not a readable VDB file: {0}")]
    Format(String),
}

/// What a grid in a `.vdb` file is, from its descriptor and metadata ([`describe`]).
#[derive(Clone, Debug, PartialEq)]
pub struct GridInfo {
    /// The grid's name.
    pub name: String,
    /// Its tree type, such as `Tree_float_5_4_3` (`_HalfFloat` appended when stored as half).
    pub tree_type: String,
    /// The world box its active voxels cover, voxels as cubes round their centres (from the
    /// `file_bbox_min`/`max` metadata and a scale-and-translate transform; `None` otherwise).
    pub extent: Option<[[f64; 3]; 2]>,
}

/// The grids of a `.vdb` file (one written with grid offsets, as OpenVDB's `File` and this
/// module write them), read from the descriptors and metadata only: the trees are skipped.
pub fn describe(bytes: &[u8]) -> Result<Vec<GridInfo>, VdbError> {
    let mut r = Cursor { b: bytes, at: 0 };
    if r.i64()? != MAGIC {
        return Err(VdbError::Format("no VDB magic number".into()));
    }
    let version = r.u32()?;
    if !(222..=FILE_VERSION + 1).contains(&version) {
        return Err(VdbError::Format(format!("file format version {version}")));
    }
    r.skip(8)?;
    if r.take(1)?[0] != 1 {
        return Err(VdbError::Format("written without grid offsets".into()));
    }
    r.skip(36)?;
    r.skip_meta()?;
    let count = r.u32()? as usize;
    // A descriptor takes at least 36 bytes: a count beyond what is left is damage.
    if count > (bytes.len() - r.at) / 36 {
        return Err(VdbError::Format(format!(
            "{count} grids in {} bytes",
            bytes.len()
        )));
    }
    let mut out = Vec::new();
    for _ in 0..count {
        let name = r.string()?;
        let tree_type = r.string()?;
        r.string()?;
        let (grid, _block, end) = (r.i64()?, r.i64()?, r.i64()?);
        r.seek(grid)?;
        r.skip(4)?;
        let (mut lo, mut hi) = (None, None);
        for _ in 0..r.u32()? {
            let key = r.string()?;
            let ty = r.string()?;
            let n = r.u32()? as usize;
            let v = r.take(n)?;
            if ty == "vec3i" && n == 12 {
                let c: [f64; 3] = std::array::from_fn(|k| {
                    i32::from_le_bytes(v[4 * k..4 * k + 4].try_into().unwrap_or([0; 4])) as f64
                });
                match key.as_str() {
                    "file_bbox_min" => lo = Some(c),
                    "file_bbox_max" => hi = Some(c),
                    _ => {}
                }
            }
        }
        let map = r.string()?;
        let mut extent = None;
        if map == "UniformScaleTranslateMap" || map == "ScaleTranslateMap" {
            let t = [r.f64()?, r.f64()?, r.f64()?];
            let s = [r.f64()?, r.f64()?, r.f64()?];
            if let (Some(lo), Some(hi)) = (lo, hi) {
                extent = Some([
                    std::array::from_fn(|k| t[k] + s[k] * (lo[k] - 0.5)),
                    std::array::from_fn(|k| t[k] + s[k] * (hi[k] + 0.5)),
                ]);
            }
        }
        out.push(GridInfo {
            name,
            tree_type,
            extent,
        });
        // Grids follow one another: an end that does not lie past this grid's data is damage.
        if end <= grid || (end as usize) < r.at {
            return Err(VdbError::Format(format!(
                "grid {:?} ends at byte {end}, before its data",
                out.last().map_or("", |g: &GridInfo| g.name.as_str())
            )));
        }
        r.seek(end)?;
    }
    Ok(out)
}

/// A bounds-checked little-endian reader for [`describe`].
struct Cursor<'a> {
    b: &'a [u8],
    at: usize,
}

impl<'a> Cursor<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], VdbError> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.b.len());
        let end = end.ok_or_else(|| VdbError::Format(format!("truncated at byte {}", self.at)))?;
        let s = &self.b[self.at..end];
        self.at = end;
        Ok(s)
    }
    fn skip(&mut self, n: usize) -> Result<(), VdbError> {
        self.take(n).map(|_| ())
    }
    fn seek(&mut self, to: i64) -> Result<(), VdbError> {
        if to < 0 || to as usize > self.b.len() {
            return Err(VdbError::Format(format!("offset {to} outside the file")));
        }
        self.at = to as usize;
        Ok(())
    }
    fn u32(&mut self) -> Result<u32, VdbError> {
        Ok(u32::from_le_bytes(
            self.take(4)?.try_into().unwrap_or([0; 4]),
        ))
    }
    fn i64(&mut self) -> Result<i64, VdbError> {
        Ok(i64::from_le_bytes(
            self.take(8)?.try_into().unwrap_or([0; 8]),
        ))
    }
    fn f64(&mut self) -> Result<f64, VdbError> {
        Ok(f64::from_le_bytes(
            self.take(8)?.try_into().unwrap_or([0; 8]),
        ))
    }
    fn string(&mut self) -> Result<String, VdbError> {
        let n = self.u32()? as usize;
        Ok(String::from_utf8_lossy(self.take(n)?).into_owned())
    }
    fn skip_meta(&mut self) -> Result<(), VdbError> {
        for _ in 0..self.u32()? {
            self.string()?;
            self.string()?;
            let n = self.u32()? as usize;
            self.skip(n)?;
        }
        Ok(())
    }
}

/// The `.vdb` file holding `grids`, in memory.
pub fn to_bytes(grids: &[DenseGrid], compression: Compression) -> Result<Vec<u8>, VdbError> {
    check(grids)?;
    let mut out = Vec::new();
    out.extend_from_slice(&MAGIC.to_le_bytes());
    put_u32(&mut out, FILE_VERSION);
    put_u32(&mut out, LIBRARY_VERSION.0);
    put_u32(&mut out, LIBRARY_VERSION.1);
    out.push(1); // has grid offsets
    let uuid_at = out.len();
    out.extend_from_slice(&[b'0'; 36]); // filled in from the content below
    // File metadata: who wrote it.
    put_u32(&mut out, 1);
    put_meta_str(
        &mut out,
        "creator",
        concat!("Weft ", env!("CARGO_PKG_VERSION")),
    );
    put_u32(&mut out, grids.len() as u32);
    let mut zip = Zip::new(compression);
    for g in grids {
        match &g.values {
            Values::Float(v) => write_grid(&mut out, g, v, &mut zip),
            Values::Vec3(v) => write_grid(&mut out, g, v, &mut zip),
        }
    }
    let uuid = uuid_from(&out);
    out[uuid_at..uuid_at + 36].copy_from_slice(uuid.as_bytes());
    Ok(out)
}

fn check(grids: &[DenseGrid]) -> Result<(), VdbError> {
    for (n, g) in grids.iter().enumerate() {
        if g.name.is_empty() || grids[..n].iter().any(|o| o.name == g.name) {
            return Err(VdbError::Name(g.name.clone()));
        }
        if g.dims.iter().any(|&d| d == 0 || d > i32::MAX as usize) {
            return Err(VdbError::Dims {
                name: g.name.clone(),
                dims: g.dims,
            });
        }
        let count = g.dims.iter().try_fold(1usize, |a, &d| a.checked_mul(d));
        if count != Some(g.values.len()) {
            return Err(VdbError::Size {
                name: g.name.clone(),
                dims: g.dims,
                found: g.values.len(),
            });
        }
        let placed = g.voxel_size.is_finite() && g.voxel_size > 0.0;
        if !(placed && g.origin.iter().all(|o| o.is_finite())) {
            return Err(VdbError::Transform {
                name: g.name.clone(),
                voxel_size: g.voxel_size,
                origin: g.origin,
            });
        }
        let bad = match &g.values {
            Values::Float(v) => v.iter().position(|x| !x.is_finite()),
            Values::Vec3(v) => v.iter().position(|x| !x.iter().all(|c| c.is_finite())),
        };
        let [nx, ny, _] = g.dims;
        let voxel = |i: usize| [i % nx, (i / nx) % ny, i / (nx * ny)];
        if let Some(i) = bad {
            return Err(VdbError::NonFinite {
                name: g.name.clone(),
                voxel: voxel(i),
            });
        }
        if g.half {
            let big = |x: f32| x.abs() > half::f16::MAX.to_f32();
            let over = match &g.values {
                Values::Float(v) => v.iter().position(|&x| big(x)),
                Values::Vec3(v) => v.iter().position(|x| x.iter().any(|&c| big(c))),
            };
            if let Some(i) = over {
                return Err(VdbError::HalfRange {
                    name: g.name.clone(),
                    voxel: voxel(i),
                });
            }
        }
    }
    Ok(())
}

/// A voxel value type OpenVDB knows.
trait Voxel: Copy {
    /// OpenVDB's name of the type in tree type names (`typeNameAsString`).
    const TYPE: &'static str;
    const ZERO: Self;
    fn put(self, out: &mut Vec<u8>);
    /// As half floats, rounded to nearest (OpenVDB's `HalfWriter`).
    fn put_half(self, out: &mut Vec<u8>);
}

impl Voxel for f32 {
    const TYPE: &'static str = "float";
    const ZERO: Self = 0.0;
    fn put(self, out: &mut Vec<u8>) {
        out.extend_from_slice(&self.to_le_bytes());
    }
    fn put_half(self, out: &mut Vec<u8>) {
        out.extend_from_slice(&half::f16::from_f32(self).to_le_bytes());
    }
}

impl Voxel for [f32; 3] {
    const TYPE: &'static str = "vec3s";
    const ZERO: Self = [0.0; 3];
    fn put(self, out: &mut Vec<u8>) {
        for c in self {
            out.extend_from_slice(&c.to_le_bytes());
        }
    }
    fn put_half(self, out: &mut Vec<u8>) {
        for c in self {
            out.extend_from_slice(&half::f16::from_f32(c).to_le_bytes());
        }
    }
}

/// Log2 of the node sizes, leaf first: 8³ leaves, 16³-child and 32³-child internal nodes.
const LOG2: [u32; 3] = [3, 4, 5];
/// Voxels spanned per axis by a leaf, a level-1 and a level-2 node.
const SPAN: [usize; 3] = [8, 128, 4096];

/// Child offsets `(a << 2L) + (b << L) + c` of the children (a, b, c) of a node of log2 size
/// `l` at `origin`, each spanning `span` voxels, that overlap the box `0..dims`, ascending.
fn children(origin: [usize; 3], l: u32, span: usize, dims: [usize; 3]) -> Vec<(usize, [usize; 3])> {
    let n = 1usize << l;
    let upto = |ax: usize| (dims[ax].saturating_sub(origin[ax])).div_ceil(span).min(n);
    let mut out = Vec::new();
    for a in 0..upto(0) {
        for b in 0..upto(1) {
            for c in 0..upto(2) {
                let off = (a << (2 * l)) + (b << l) + c;
                let o = [
                    origin[0] + a * span,
                    origin[1] + b * span,
                    origin[2] + c * span,
                ];
                out.push((off, o));
            }
        }
    }
    out
}

/// A bit mask of `bits` bits, saved as little-endian u64 words (`util::NodeMask::save`).
fn put_mask(out: &mut Vec<u8>, bits: usize, on: impl Iterator<Item = usize>) {
    let mut words = vec![0u64; bits / 64];
    for n in on {
        words[n >> 6] |= 1 << (n & 63);
    }
    for w in words {
        out.extend_from_slice(&w.to_le_bytes());
    }
}

fn write_grid<T: Voxel>(out: &mut Vec<u8>, g: &DenseGrid, data: &[T], zip: &mut Zip) {
    zip.half = g.half;
    // Descriptor: unique name, tree type, instance parent, then three offsets patched below.
    put_str(out, &g.name);
    // A half grid's descriptor names its type with OpenVDB's `_HalfFloat` suffix.
    let suffix = if g.half { "_HalfFloat" } else { "" };
    put_str(out, &format!("Tree_{}_5_4_3{suffix}", T::TYPE));
    put_str(out, "");
    let offsets_at = out.len();
    out.extend_from_slice(&[0u8; 24]);
    let grid_pos = out.len();
    put_u32(out, if zip.on { COMPRESS_ZIP } else { 0 });

    // Metadata, in name order (OpenVDB keeps a std::map).
    let [nx, ny, nz] = g.dims;
    let is_vec = T::TYPE == "vec3s";
    put_u32(out, if is_vec { 8 } else { 7 });
    put_meta_str(out, "class", g.class.as_str());
    put_meta(
        out,
        "file_bbox_max",
        "vec3i",
        &ivec([nx - 1, ny - 1, nz - 1]),
    );
    put_meta(out, "file_bbox_min", "vec3i", &ivec([0, 0, 0]));
    put_meta(
        out,
        "file_voxel_count",
        "int64",
        &((nx * ny * nz) as i64).to_le_bytes(),
    );
    put_meta(out, "is_local_space", "bool", &[0]);
    put_meta(out, "is_saved_as_half_float", "bool", &[g.half as u8]);
    put_meta_str(out, "name", &g.name);
    if is_vec {
        put_meta_str(out, "vector_type", g.vector_type.as_str());
    }

    // Transform: index (i, j, k) → origin + voxel_size (i, j, k).
    put_str(out, "UniformScaleTranslateMap");
    let s = g.voxel_size;
    for v in [
        g.origin,
        [s; 3],
        [s; 3],
        [1.0 / s; 3],
        [1.0 / (s * s); 3],
        [0.5 / s; 3],
    ] {
        for c in v {
            out.extend_from_slice(&c.to_le_bytes());
        }
    }

    // Topology: buffer count, root (background, tiles, children), then each internal node's
    // child mask, value mask and tile values, and each leaf's value mask.
    out.extend_from_slice(&1i32.to_le_bytes());
    T::ZERO.put(out);
    // Root children: the 4096³ blocks the box touches, in (x, y, z) lexicographic order.
    let blocks = |ax: usize| g.dims[ax].div_ceil(SPAN[2]);
    let roots: Vec<[usize; 3]> = (0..blocks(0))
        .flat_map(|a| (0..blocks(1)).flat_map(move |b| (0..blocks(2)).map(move |c| [a, b, c])))
        .map(|abc| abc.map(|n| n * SPAN[2]))
        .collect();
    put_u32(out, 0); // tiles
    put_u32(out, roots.len() as u32);
    let mut leaves = Vec::new();
    for &o2 in &roots {
        for c in o2 {
            out.extend_from_slice(&(c as i32).to_le_bytes());
        }
        let n2 = children(o2, LOG2[2], SPAN[1], g.dims);
        put_mask(out, 1 << (3 * LOG2[2]), n2.iter().map(|c| c.0));
        put_mask(out, 1 << (3 * LOG2[2]), std::iter::empty());
        zip.put_zeros::<T>(out, 1 << (3 * LOG2[2]));
        for &(_, o1) in &n2 {
            let n1 = children(o1, LOG2[1], SPAN[0], g.dims);
            put_mask(out, 1 << (3 * LOG2[1]), n1.iter().map(|c| c.0));
            put_mask(out, 1 << (3 * LOG2[1]), std::iter::empty());
            zip.put_zeros::<T>(out, 1 << (3 * LOG2[1]));
            for &(_, o0) in &n1 {
                leaf_mask(out, o0, g.dims);
                leaves.push(o0);
            }
        }
    }

    // Buffers: per leaf, its value mask again, the indicator byte and its 512 values.
    let block_pos = out.len();
    let mut values = Vec::with_capacity(512);
    for o in leaves {
        leaf_mask(out, o, g.dims);
        values.clear();
        for a in 0..8 {
            for b in 0..8 {
                for c in 0..8 {
                    let (x, y, z) = (o[0] + a, o[1] + b, o[2] + c);
                    values.push(if x < nx && y < ny && z < nz {
                        data[x + nx * (y + ny * z)]
                    } else {
                        T::ZERO
                    });
                }
            }
        }
        out.push(ALL_VALUES);
        zip.put(out, &values);
    }
    let end_pos = out.len();
    for (k, p) in [grid_pos, block_pos, end_pos].into_iter().enumerate() {
        out[offsets_at + 8 * k..offsets_at + 8 * k + 8].copy_from_slice(&(p as i64).to_le_bytes());
    }
}

fn leaf_mask(out: &mut Vec<u8>, o: [usize; 3], dims: [usize; 3]) {
    let inside = |ax: usize| dims[ax].saturating_sub(o[ax]).min(8);
    let (ia, ib, ic) = (inside(0), inside(1), inside(2));
    let on = (0..ia).flat_map(move |a| {
        (0..ib).flat_map(move |b| (0..ic).map(move |c| (a << 6) + (b << 3) + c))
    });
    put_mask(out, 512, on);
}

/// Node value writer: raw, or zlib with OpenVDB's framing; keeps its buffers across nodes.
struct Zip {
    on: bool,
    /// Node values as half floats (the root's background stays full size, as OpenVDB's).
    half: bool,
    raw: Vec<u8>,
    packed: Vec<u8>,
    deflate: flate2::Compress,
}

impl Zip {
    fn new(c: Compression) -> Self {
        Zip {
            on: c == Compression::Zip,
            half: false,
            raw: Vec::new(),
            packed: Vec::new(),
            deflate: flate2::Compress::new(flate2::Compression::fast(), true),
        }
    }

    fn put_zeros<T: Voxel>(&mut self, out: &mut Vec<u8>, count: usize) {
        out.push(ALL_VALUES);
        let zeros = vec![T::ZERO; count];
        self.put(out, &zeros);
    }

    fn put<T: Voxel>(&mut self, out: &mut Vec<u8>, values: &[T]) {
        self.raw.clear();
        for &v in values {
            if self.half {
                v.put_half(&mut self.raw);
            } else {
                v.put(&mut self.raw);
            }
        }
        if !self.on {
            out.extend_from_slice(&self.raw);
            return;
        }
        // zlib's bound for one-shot compression: n + n/1000 + 64 is ample.
        self.packed.clear();
        self.packed
            .reserve(self.raw.len() + self.raw.len() / 1000 + 64);
        self.deflate.reset();
        let done =
            self.deflate
                .compress_vec(&self.raw, &mut self.packed, flate2::FlushCompress::Finish);
        let complete = matches!(done, Ok(flate2::Status::StreamEnd));
        if complete && self.packed.len() < self.raw.len() {
            out.extend_from_slice(&(self.packed.len() as i64).to_le_bytes());
            out.extend_from_slice(&self.packed);
        } else {
            out.extend_from_slice(&(-(self.raw.len() as i64)).to_le_bytes());
            out.extend_from_slice(&self.raw);
        }
    }
}

fn put_u32(out: &mut Vec<u8>, v: u32) {
    out.extend_from_slice(&v.to_le_bytes());
}

/// A string: u32 length, then its bytes (`writeString`).
fn put_str(out: &mut Vec<u8>, s: &str) {
    put_u32(out, s.len() as u32);
    out.extend_from_slice(s.as_bytes());
}

/// A metadata entry: name, type name, u32 byte count, value.
fn put_meta(out: &mut Vec<u8>, name: &str, type_name: &str, value: &[u8]) {
    put_str(out, name);
    put_str(out, type_name);
    put_u32(out, value.len() as u32);
    out.extend_from_slice(value);
}

fn put_meta_str(out: &mut Vec<u8>, name: &str, value: &str) {
    put_meta(out, name, "string", value.as_bytes());
}

fn ivec(v: [usize; 3]) -> Vec<u8> {
    v.iter().flat_map(|&c| (c as i32).to_le_bytes()).collect()
}

/// A UUID-shaped tag from the content (FNV-1a, 128 bits), so equal inputs give equal files.
fn uuid_from(bytes: &[u8]) -> String {
    let mut h: u128 = 0x6c62272e07bb014262b821756295c58d;
    for &b in bytes {
        h ^= b as u128;
        h = h.wrapping_mul(0x0000000001000000000000000000013B);
    }
    let hex = format!("{h:032X}");
    format!(
        "{}-{}-{}-{}-{}",
        &hex[0..8],
        &hex[8..12],
        &hex[12..16],
        &hex[16..20],
        &hex[20..32]
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A reader for what this writer produces (no tiles, one buffer, indicator 6), enough to
    /// check the tree's layout independently of the writer's loops: it places each leaf's
    /// values by the offsets the file states, walking the masks as OpenVDB does.
    struct Reader<'a> {
        b: &'a [u8],
        at: usize,
    }

    impl<'a> Reader<'a> {
        fn take(&mut self, n: usize) -> &'a [u8] {
            let s = &self.b[self.at..self.at + n];
            self.at += n;
            s
        }
        fn u32(&mut self) -> u32 {
            u32::from_le_bytes(self.take(4).try_into().unwrap())
        }
        fn i32(&mut self) -> i32 {
            i32::from_le_bytes(self.take(4).try_into().unwrap())
        }
        fn i64(&mut self) -> i64 {
            i64::from_le_bytes(self.take(8).try_into().unwrap())
        }
        fn f64(&mut self) -> f64 {
            f64::from_le_bytes(self.take(8).try_into().unwrap())
        }
        fn string(&mut self) -> String {
            let n = self.u32() as usize;
            String::from_utf8(self.take(n).to_vec()).unwrap()
        }
        fn mask(&mut self, bits: usize) -> Vec<usize> {
            let words = self.take(bits / 8);
            (0..bits)
                .filter(|&n| words[n / 8] >> (n % 8) & 1 == 1)
                .collect()
        }
        fn values_as(&mut self, count: usize, width: usize, zip: bool, half: bool) -> Vec<f32> {
            let size = if half { 2 } else { 4 };
            assert_eq!(self.take(1)[0], ALL_VALUES);
            let raw = if zip {
                let n = self.i64();
                if n < 0 {
                    self.take((-n) as usize).to_vec()
                } else {
                    let mut d = flate2::Decompress::new(true);
                    let mut v = Vec::with_capacity(count * width * size);
                    d.decompress_vec(
                        self.take(n as usize),
                        &mut v,
                        flate2::FlushDecompress::Finish,
                    )
                    .unwrap();
                    v
                }
            } else {
                self.take(count * width * size).to_vec()
            };
            assert_eq!(raw.len(), count * width * size);
            raw.chunks(size)
                .map(|c| match c.len() {
                    2 => half::f16::from_le_bytes(c.try_into().unwrap()).to_f32(),
                    _ => f32::from_le_bytes(c.try_into().unwrap()),
                })
                .collect()
        }
    }

    struct ReadGrid {
        name: String,
        tree: String,
        meta: Vec<(String, String)>,
        translation: [f64; 3],
        voxel: f64,
        /// (voxel index, components) of every active voxel.
        active: Vec<([i64; 3], Vec<f32>)>,
    }

    fn read(bytes: &[u8]) -> Vec<ReadGrid> {
        let mut r = Reader { b: bytes, at: 0 };
        assert_eq!(r.i64(), MAGIC);
        assert_eq!(r.u32(), FILE_VERSION);
        r.take(8);
        assert_eq!(r.take(1)[0], 1);
        let uuid = std::str::from_utf8(r.take(36)).unwrap().to_string();
        assert_eq!(uuid.matches('-').count(), 4);
        for _ in 0..r.u32() {
            r.string();
            r.string();
            let n = r.u32() as usize;
            r.take(n);
        }
        let mut grids = Vec::new();
        for _ in 0..r.u32() {
            let name = r.string();
            let tree = r.string();
            assert_eq!(r.string(), "");
            let (gp, bp, ep) = (r.i64() as usize, r.i64() as usize, r.i64() as usize);
            assert_eq!(r.at, gp, "grid position");
            let zip = r.u32() == COMPRESS_ZIP;
            let mut meta = Vec::new();
            for _ in 0..r.u32() {
                let k = r.string();
                let t = r.string();
                let n = r.u32() as usize;
                let v = r.take(n);
                meta.push((
                    k,
                    if t == "string" {
                        String::from_utf8(v.to_vec()).unwrap()
                    } else {
                        t
                    },
                ));
            }
            assert_eq!(r.string(), "UniformScaleTranslateMap");
            let translation = [r.f64(), r.f64(), r.f64()];
            let voxel = r.f64();
            r.take(8 * 14);
            let width = if tree.contains("vec3s") { 3 } else { 1 };
            let half = tree.ends_with("_HalfFloat");
            assert_eq!(r.i32(), 1);
            assert!(r.values_bg(width));
            assert_eq!(r.u32(), 0, "no tiles");
            let mut leaf_origins = Vec::new();
            for _ in 0..r.u32() {
                let o2 = [r.i32() as i64, r.i32() as i64, r.i32() as i64];
                let kids2 = r.mask(1 << 15);
                assert!(r.mask(1 << 15).is_empty());
                assert!(
                    r.values_as(1 << 15, width, zip, half)
                        .iter()
                        .all(|&v| v == 0.0)
                );
                for n2 in kids2 {
                    let o1 = offset(o2, n2, 5, 128);
                    let kids1 = r.mask(1 << 12);
                    assert!(r.mask(1 << 12).is_empty());
                    assert!(
                        r.values_as(1 << 12, width, zip, half)
                            .iter()
                            .all(|&v| v == 0.0)
                    );
                    for n1 in kids1 {
                        leaf_origins.push((offset(o1, n1, 4, 8), r.mask(512)));
                    }
                }
            }
            assert_eq!(r.at, bp, "block position");
            let mut active = Vec::new();
            for (o, m) in leaf_origins {
                assert_eq!(r.mask(512), m);
                let v = r.values_as(512, width, zip, half);
                for n in m {
                    active.push((offset(o, n, 3, 1), v[n * width..(n + 1) * width].to_vec()));
                }
            }
            assert_eq!(r.at, ep, "end position");
            grids.push(ReadGrid {
                name,
                tree,
                meta,
                translation,
                voxel,
                active,
            });
        }
        assert_eq!(r.at, bytes.len());
        grids
    }

    impl Reader<'_> {
        fn values_bg(&mut self, width: usize) -> bool {
            (0..width).all(|_| f32::from_le_bytes(self.take(4).try_into().unwrap()) == 0.0)
        }
    }

    fn offset(origin: [i64; 3], n: usize, l: u32, span: i64) -> [i64; 3] {
        let m = (1usize << l) - 1;
        let (a, b, c) = (n >> (2 * l), (n >> l) & m, n & m);
        [
            origin[0] + a as i64 * span,
            origin[1] + b as i64 * span,
            origin[2] + c as i64 * span,
        ]
    }

    fn field(dims: [usize; 3]) -> Vec<f32> {
        let mut v = Vec::new();
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    v.push((i as f32) + 1000.0 * j as f32 + 0.5 * k as f32 + 0.25);
                }
            }
        }
        v
    }

    #[test]
    fn every_voxel_is_read_back_where_it_was_written() {
        // 130 voxels along x crosses a 128-voxel internal node; 9 along z a leaf.
        for compression in [Compression::None, Compression::Zip] {
            let dims = [130, 3, 9];
            let s = field(dims);
            let v: Vec<[f32; 3]> = s.iter().map(|&x| [x, -x, 2.0 * x]).collect();
            let grids = vec![
                DenseGrid {
                    name: "pressure".into(),
                    class: GridClass::Unknown,
                    vector_type: VectorType::Invariant,
                    dims,
                    voxel_size: 0.04,
                    origin: [-0.58, 0.52, -0.28],
                    values: Values::Float(s.clone()),
                    half: false,
                },
                DenseGrid {
                    name: "velocity".into(),
                    class: GridClass::Unknown,
                    vector_type: VectorType::ContravariantRelative,
                    dims,
                    voxel_size: 0.04,
                    origin: [-0.58, 0.52, -0.28],
                    values: Values::Vec3(v),
                    half: false,
                },
            ];
            let bytes = to_bytes(&grids, compression).unwrap();
            let back = read(&bytes);
            assert_eq!(back.len(), 2);
            for (g, w) in back.iter().zip([1usize, 3]) {
                assert_eq!(
                    g.tree,
                    if w == 1 {
                        "Tree_float_5_4_3"
                    } else {
                        "Tree_vec3s_5_4_3"
                    }
                );
                assert_eq!(g.translation, [-0.58, 0.52, -0.28]);
                assert_eq!(g.voxel, 0.04);
                assert_eq!(g.active.len(), 130 * 3 * 9, "{}", g.name);
                for (ijk, val) in &g.active {
                    let [i, j, k] = ijk.map(|c| c as usize);
                    assert!(i < 130 && j < 3 && k < 9, "{ijk:?}");
                    let x = s[i + 130 * (j + 3 * k)];
                    let want = if w == 1 {
                        vec![x]
                    } else {
                        vec![x, -x, 2.0 * x]
                    };
                    assert_eq!(val, &want, "{} at {ijk:?}", g.name);
                }
            }
            let meta =
                |g: &ReadGrid, k: &str| g.meta.iter().find(|(n, _)| n == k).map(|(_, v)| v.clone());
            assert_eq!(meta(&back[0], "name").as_deref(), Some("pressure"));
            assert_eq!(meta(&back[0], "class").as_deref(), Some("unknown"));
            assert_eq!(meta(&back[0], "vector_type"), None);
            assert_eq!(
                meta(&back[1], "vector_type").as_deref(),
                Some("contravariant relative")
            );
            let names: Vec<&str> = back[1].meta.iter().map(|(n, _)| n.as_str()).collect();
            let mut sorted = names.clone();
            sorted.sort();
            assert_eq!(names, sorted, "metadata in name order, as OpenVDB's map");
        }
    }

    #[test]
    fn zip_compresses_and_the_output_is_deterministic() {
        let dims = [64, 64, 64];
        let g = DenseGrid {
            name: "speed".into(),
            class: GridClass::FogVolume,
            vector_type: VectorType::Invariant,
            dims,
            voxel_size: 1.0 / 64.0,
            origin: [0.0; 3],
            values: Values::Float(vec![1.5; 64 * 64 * 64]),
            half: false,
        };
        let raw = to_bytes(std::slice::from_ref(&g), Compression::None).unwrap();
        let zip = to_bytes(std::slice::from_ref(&g), Compression::Zip).unwrap();
        // A constant field: 1 MiB of floats compresses by more than 10× (the masks stay raw).
        assert!(raw.len() > 64 * 64 * 64 * 4, "{}", raw.len());
        assert!(zip.len() * 10 < raw.len(), "{} vs {}", zip.len(), raw.len());
        assert_eq!(zip, to_bytes(&[g], Compression::Zip).unwrap());
        assert_eq!(read(&zip)[0].active.len(), 64 * 64 * 64);
    }

    #[test]
    fn bad_grids_are_refused_with_the_grid_named() {
        let good = DenseGrid {
            name: "p".into(),
            class: GridClass::Unknown,
            vector_type: VectorType::Invariant,
            dims: [2, 2, 2],
            voxel_size: 0.1,
            origin: [0.0; 3],
            values: Values::Float(vec![0.0; 8]),
            half: false,
        };
        let with = |f: &dyn Fn(&mut DenseGrid)| {
            let mut g = good.clone();
            f(&mut g);
            to_bytes(&[g], Compression::Zip).unwrap_err().to_string()
        };
        assert!(with(&|g| g.values = Values::Float(vec![0.0; 7])).contains("7 values"));
        assert!(with(&|g| g.dims = [0, 2, 2]).contains("each axis"));
        assert!(with(&|g| g.voxel_size = 0.0).contains("voxel size"));
        assert!(with(&|g| g.origin[1] = f64::NAN).contains("origin"));
        let nan = with(&|g| g.values = Values::Float(vec![0., 0., 0., f32::NAN, 0., 0., 0., 0.]));
        assert!(
            nan.contains("grid `p`") && nan.contains("[1, 1, 0]"),
            "{nan}"
        );
        assert!(with(&|g| g.name.clear()).contains("name"));
        let twice = to_bytes(&[good.clone(), good], Compression::None).unwrap_err();
        assert!(twice.to_string().contains("\"p\""), "{twice}");
    }

    #[test]
    fn describe_reads_names_types_and_extent_and_refuses_damage() {
        let g = |name: &str, values| DenseGrid {
            name: name.into(),
            class: GridClass::Unknown,
            vector_type: VectorType::ContravariantRelative,
            dims: [4, 3, 2],
            voxel_size: 0.5,
            origin: [1.0, 2.0, 3.0],
            values,
            half: false,
        };
        let bytes = to_bytes(
            &[
                g("velocity", Values::Vec3(vec![[0.0; 3]; 24])),
                g("speed", Values::Float(vec![1.0; 24])),
            ],
            Compression::Zip,
        )
        .unwrap();
        let info = describe(&bytes).unwrap();
        assert_eq!(info.len(), 2);
        assert_eq!(
            (info[0].name.as_str(), info[0].tree_type.as_str()),
            ("velocity", "Tree_vec3s_5_4_3")
        );
        assert_eq!(info[1].tree_type, "Tree_float_5_4_3");
        // Voxel centres 1.0 .. 2.5 along x (4 voxels of 0.5 m): the box is 0.75 .. 2.75.
        assert_eq!(
            info[1].extent,
            Some([[0.75, 1.75, 2.75], [2.75, 3.25, 3.75]])
        );
        for cut in [0, 7, 40, bytes.len() / 2, bytes.len() - 1] {
            assert!(describe(&bytes[..cut]).is_err(), "cut at {cut}");
        }
        assert!(describe(b"not a vdb file at all").is_err());
        // A grid whose end points back at its own descriptor would be read again and again.
        let mut looping = bytes.clone();
        let first = info_offsets(&bytes);
        looping[first.0..first.0 + 8].copy_from_slice(&(first.1 as i64).to_le_bytes());
        assert!(describe(&looping).is_err());
    }

    #[test]
    fn half_grids_store_half_floats_and_refuse_what_half_cannot_hold() {
        let dims = [9, 2, 3];
        let s = field(dims);
        let g = DenseGrid {
            name: "speed".into(),
            class: GridClass::Unknown,
            vector_type: VectorType::Invariant,
            dims,
            voxel_size: 0.1,
            origin: [0.0; 3],
            values: Values::Float(s.clone()),
            half: true,
        };
        for compression in [Compression::None, Compression::Zip] {
            let bytes = to_bytes(std::slice::from_ref(&g), compression).unwrap();
            let back = read(&bytes);
            assert_eq!(back[0].tree, "Tree_float_5_4_3_HalfFloat");
            assert_eq!(back[0].active.len(), 54);
            for (ijk, v) in &back[0].active {
                let [i, j, k] = ijk.map(|c| c as usize);
                let want = half::f16::from_f32(s[i + 9 * (j + 2 * k)]).to_f32();
                assert_eq!(v, &vec![want], "{ijk:?}");
            }
        }
        let raw = to_bytes(std::slice::from_ref(&g), Compression::None).unwrap();
        let full = DenseGrid {
            half: false,
            ..g.clone()
        };
        let raw_full = to_bytes(&[full], Compression::None).unwrap();
        // Two leaves (9 voxels along x) and two internal nodes' values at 2 bytes instead
        // of 4, less the type name's 10-byte "_HalfFloat".
        assert_eq!(
            raw_full.len() - raw.len(),
            2 * (2 * 512 + 4096 + 32768) - 10
        );
        let mut big = g;
        if let Values::Float(v) = &mut big.values {
            v[10] = 70000.0;
        }
        let e = to_bytes(&[big], Compression::Zip).unwrap_err().to_string();
        assert!(
            e.contains("grid `speed`") && e.contains("[1, 1, 0]") && e.contains("65504"),
            "{e}"
        );
    }

    /// Where the first grid's end offset is stored, and where its descriptor starts.
    fn info_offsets(bytes: &[u8]) -> (usize, usize) {
        let mut r = Cursor { b: bytes, at: 0 };
        r.skip(8 + 12 + 1 + 36).unwrap();
        r.skip_meta().unwrap();
        r.u32().unwrap();
        let start = r.at;
        r.string().unwrap();
        r.string().unwrap();
        r.string().unwrap();
        (r.at + 16, start)
    }
}
