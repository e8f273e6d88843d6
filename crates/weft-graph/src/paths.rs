//! Where output files go: with an output root (`weft run --out DIR`) every path an output
//! node writes resolves under it, so two runs with two output directories never write into
//! each other's, and a graph file cannot write outside the root.

use std::path::{Component, Path, PathBuf};

/// `p` with `.` and `..` resolved lexically (`None` when `..` climbs above its start).
fn normalize(p: &Path) -> Option<PathBuf> {
    let mut out = PathBuf::new();
    let mut depth = 0usize;
    for c in p.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                if depth == 0 {
                    return None;
                }
                out.pop();
                depth -= 1;
            }
            Component::Normal(x) => {
                out.push(x);
                depth += 1;
            }
            Component::RootDir | Component::Prefix(_) => out.push(c.as_os_str()),
        }
    }
    Some(out)
}

/// Resolves an output path `rel` under `root`. A relative path may not climb out of the
/// root with `..`; an absolute one must lie inside it. Without a root (`weft run` without
/// `--out`, a program embedding the engine) the path is used as given, relative to the
/// working directory.
pub fn resolve_output(root: Option<&Path>, rel: &str) -> Result<PathBuf, String> {
    if rel.is_empty() {
        return Err("an output path must not be empty".into());
    }
    let Some(base) = root else {
        return Ok(PathBuf::from(rel));
    };
    let where_ = || format!("the output directory '{}' (--out)", base.display());
    let p = Path::new(rel);
    if p.is_absolute() {
        let cwd = std::env::current_dir().map_err(|e| format!("no working directory: {e}"))?;
        let abs_root = normalize(&cwd.join(base)).unwrap_or(cwd);
        return match normalize(p) {
            Some(n) if n.starts_with(&abs_root) => Ok(n),
            _ => Err(format!("'{rel}' is outside {}", where_())),
        };
    }
    match normalize(p) {
        Some(n) if n.as_os_str().is_empty() => Ok(base.to_path_buf()),
        Some(n) => Ok(base.join(n)),
        None => Err(format!("'{rel}' climbs out of {}", where_())),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outputs_stay_under_the_root() {
        let r = Some(Path::new("a"));
        assert_eq!(
            resolve_output(r, "out/x.usda").unwrap(),
            Path::new("a/out/x.usda")
        );
        assert_eq!(resolve_output(r, "./out/../y").unwrap(), Path::new("a/y"));
        assert_eq!(
            resolve_output(None, "out/obj").unwrap(),
            Path::new("out/obj")
        );
        assert!(
            resolve_output(r, "../b")
                .unwrap_err()
                .contains("climbs out of")
        );
        assert!(resolve_output(r, "out/../../b").is_err());
        assert_eq!(resolve_output(None, "/tmp/x").unwrap(), Path::new("/tmp/x"));
        assert!(resolve_output(r, "/etc/x").unwrap_err().contains("outside"));
        assert!(resolve_output(r, "").is_err());
        let cwd = std::env::current_dir().unwrap();
        let inside = cwd.join("a/deep/file");
        assert_eq!(resolve_output(r, inside.to_str().unwrap()).unwrap(), inside);
    }
}
