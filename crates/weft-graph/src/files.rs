//! Files written so that nothing is ever half there: atomic writes (temporary file, flush to
//! disk, rename), the removal of temporaries killed writers left, and the framed records
//! (magic, key, frame, type, payload, checksum) of disk caches and checkpoints.

use std::io::Write;
use std::path::{Path, PathBuf};

const TMP_PREFIX: &str = ".weft-tmp-";

/// Removes the temporary files that killed processes left in `dir` (named
/// `.weft-tmp-PID-…`, PID no longer running), once per directory per process. A file of a
/// process that is still running (another run writing there) is left alone.
fn sweep_stale_temporaries(dir: &Path) {
    static SWEPT: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());
    let Ok(mut swept) = SWEPT.lock() else { return };
    if swept.iter().any(|d| d == dir) || !Path::new("/proc/self").exists() {
        return;
    }
    swept.push(dir.to_path_buf());
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let name = e.file_name();
        let Some(rest) = name.to_str().and_then(|n| n.strip_prefix(TMP_PREFIX)) else {
            continue;
        };
        let pid = rest.split('-').next().and_then(|p| p.parse::<u32>().ok());
        if let Some(pid) = pid
            && pid != std::process::id()
            && !Path::new(&format!("/proc/{pid}")).exists()
        {
            let _ = std::fs::remove_file(e.path());
        }
    }
}

/// Writes a file atomically: `fill` writes into a temporary file next to `path`, which is
/// flushed to disk and renamed over `path` only if `fill` succeeds, so a reader (or a run
/// killed at any moment) sees the old file or the new one, never a part. On error the
/// temporary file is removed; one a killed process left behind is removed by the next
/// write into the same directory.
pub fn atomic_write_with(
    path: &Path,
    fill: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> std::io::Result<()> {
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir)?;
    sweep_stale_temporaries(dir);
    let prefix = format!("{TMP_PREFIX}{}-", std::process::id());
    let mut builder = tempfile::Builder::new();
    builder.prefix(&prefix);
    // A temporary file is private (0600) by default; the file it becomes is an output others
    // read (a renderer on a farm, a colleague), so it gets the mode any program's new file
    // gets: 0666 less the umask.
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        builder.permissions(std::fs::Permissions::from_mode(0o666));
    }
    let mut tmp = builder.tempfile_in(dir)?;
    {
        let mut w = std::io::BufWriter::new(tmp.as_file_mut());
        fill(&mut w)?;
        w.flush()?;
    }
    tmp.as_file().sync_data()?;
    tmp.persist(path).map_err(|e| e.error)?;
    Ok(())
}

/// Writes `bytes` to `path` atomically.
pub fn atomic_write(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    atomic_write_with(path, |w| w.write_all(bytes))
}

const MAGIC: &[u8; 10] = b"WEFTCACHE\x01";

/// Serializes one cached frame: magic, key, frame, type name, payload, checksum.
pub(crate) fn encode_frame(key: u128, frame: i64, type_name: &str, payload: &[u8]) -> Vec<u8> {
    let mut b = Vec::with_capacity(payload.len() + 64);
    b.extend_from_slice(MAGIC);
    b.extend_from_slice(&key.to_le_bytes());
    b.extend_from_slice(&frame.to_le_bytes());
    b.extend_from_slice(&(type_name.len() as u16).to_le_bytes());
    b.extend_from_slice(type_name.as_bytes());
    b.extend_from_slice(&(payload.len() as u64).to_le_bytes());
    b.extend_from_slice(payload);
    let sum = xxhash_rust::xxh3::xxh3_64(&b);
    b.extend_from_slice(&sum.to_le_bytes());
    b
}

/// Parses a cached frame; `None` for anything corrupt, truncated or of another key.
pub(crate) fn decode_frame(b: &[u8], key: u128, frame: i64) -> Option<(String, &[u8])> {
    let body_len = b.len().checked_sub(8)?;
    let (body, sum) = b.split_at(body_len);
    if xxhash_rust::xxh3::xxh3_64(body).to_le_bytes() != sum {
        return None;
    }
    let rest = body.strip_prefix(MAGIC)?;
    let (k, rest) = rest.split_at_checked(16)?;
    let (f, rest) = rest.split_at_checked(8)?;
    if u128::from_le_bytes(k.try_into().ok()?) != key
        || i64::from_le_bytes(f.try_into().ok()?) != frame
    {
        return None;
    }
    let (n, rest) = rest.split_at_checked(2)?;
    let (name, rest) = rest.split_at_checked(u16::from_le_bytes(n.try_into().ok()?) as usize)?;
    let (len, payload) = rest.split_at_checked(8)?;
    if u64::from_le_bytes(len.try_into().ok()?) as usize != payload.len() {
        return None;
    }
    Some((String::from_utf8(name.to_vec()).ok()?, payload))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_codec_rejects_corruption_and_other_keys() {
        let b = encode_frame(42, 7, "float", &1.5f64.to_le_bytes());
        let (t, p) = decode_frame(&b, 42, 7).unwrap();
        assert_eq!((t.as_str(), p), ("float", &1.5f64.to_le_bytes()[..]));
        assert!(decode_frame(&b, 43, 7).is_none(), "another key");
        assert!(decode_frame(&b, 42, 8).is_none(), "another frame");
        for cut in 0..b.len() {
            assert!(
                decode_frame(&b[..cut], 42, 7).is_none(),
                "truncated at {cut}"
            );
        }
        let mut flipped = b.clone();
        flipped[30] ^= 1;
        assert!(decode_frame(&flipped, 42, 7).is_none(), "bit flip");
    }

    #[test]
    fn interrupted_write_leaves_no_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("frame.wcache");
        atomic_write(&path, b"old").unwrap();
        let r = atomic_write_with(&path, |w| {
            w.write_all(b"half of the new")?;
            Err(std::io::Error::other("killed"))
        });
        assert!(r.is_err());
        // The old content is intact and no temporary file is left behind.
        assert_eq!(std::fs::read(&path).unwrap(), b"old");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    /// Outputs are readable by others as any new file is (0666 less the umask), not private
    /// like the temporary they are written through.
    #[cfg(unix)]
    #[test]
    fn written_files_get_the_usual_mode() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.vdb");
        atomic_write(&path, b"x").unwrap();
        let mode = std::fs::metadata(&path).unwrap().permissions().mode() & 0o777;
        // The umask, read back from a file created the ordinary way.
        let plain = dir.path().join("plain");
        std::fs::write(&plain, b"x").unwrap();
        let want = std::fs::metadata(&plain).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, want, "{mode:o} vs {want:o}");
    }
}
