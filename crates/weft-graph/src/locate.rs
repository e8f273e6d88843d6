//! Positions of keys in JSON text, and duplicate keys.
//!
//! serde_json keeps neither positions nor duplicate object keys (the last one silently wins),
//! so one linear scan over the already-parsed text records the line and column of every object
//! key and array element by path. Diagnostics then find their line by path.

use std::collections::HashMap;

/// Separator between path components (cannot appear in a parsed key by accident of JSON text).
const SEP: char = '\u{1f}';

pub(crate) fn key(path: &[String]) -> String {
    path.join(&SEP.to_string())
}

#[derive(Default)]
pub(crate) struct Locations {
    map: HashMap<String, (usize, usize)>,
    /// (path of the repeated key, line, column)
    pub duplicates: Vec<(Vec<String>, usize, usize)>,
}

impl Locations {
    /// The position of the deepest known prefix of `path`.
    pub fn find(&self, path: &[String]) -> Option<(usize, usize)> {
        (0..=path.len())
            .rev()
            .find_map(|n| self.map.get(&key(&path[..n])).copied())
    }
}

struct Scanner<'a> {
    b: &'a [u8],
    i: usize,
    line: usize,
    line_start: usize,
    out: Locations,
    /// Record every position (slow path, only when a diagnostic needs a line).
    positions: bool,
    /// Raw keys seen per open object, one reusable set per nesting depth.
    seen: Vec<std::collections::HashSet<&'a [u8]>>,
    depth: usize,
}

#[derive(Clone, Copy)]
enum Item<'a> {
    Key(&'a [u8]),
    Index(usize),
}

fn owned(path: &[Item<'_>]) -> Vec<String> {
    path.iter()
        .map(|i| match i {
            Item::Key(raw) => serde_json::from_slice::<String>(raw).unwrap_or_default(),
            Item::Index(n) => n.to_string(),
        })
        .collect()
}

impl<'a> Scanner<'a> {
    fn column(&self, line_start: usize, at: usize) -> usize {
        // Columns count characters, not bytes.
        String::from_utf8_lossy(&self.b[line_start..at])
            .chars()
            .count()
            + 1
    }
    fn ws(&mut self) {
        while let Some(&c) = self.b.get(self.i) {
            match c {
                b'\n' => {
                    self.i += 1;
                    self.line += 1;
                    self.line_start = self.i;
                }
                b' ' | b'\t' | b'\r' => self.i += 1,
                _ => break,
            }
        }
    }
    /// Skips a string token, returning its raw bytes (quotes included).
    fn raw_string(&mut self) -> &'a [u8] {
        let start = self.i;
        self.i += 1;
        while let Some(&c) = self.b.get(self.i) {
            self.i += 1;
            match c {
                b'\\' => self.i += 1,
                b'"' => break,
                _ => {}
            }
        }
        let b: &'a [u8] = self.b;
        &b[start..self.i.min(b.len())]
    }
    fn value(&mut self, path: &mut Vec<Item<'a>>) {
        self.ws();
        match self.b.get(self.i) {
            Some(b'{') => {
                self.i += 1;
                if self.seen.len() <= self.depth {
                    self.seen.push(Default::default());
                }
                self.seen[self.depth].clear();
                self.depth += 1;
                loop {
                    self.ws();
                    match self.b.get(self.i) {
                        Some(b'}') | None => {
                            self.i += 1;
                            self.depth -= 1;
                            return;
                        }
                        Some(b',') => {
                            self.i += 1;
                            continue;
                        }
                        _ => {}
                    }
                    let (line, line_start, at) = (self.line, self.line_start, self.i);
                    let raw = self.raw_string();
                    let fresh = self.seen[self.depth - 1].insert(raw);
                    path.push(Item::Key(raw));
                    if !fresh {
                        let col = self.column(line_start, at);
                        self.out.duplicates.push((owned(path), line, col));
                    } else if self.positions {
                        // The first occurrence wins; a duplicate's children must not move it.
                        let col = self.column(line_start, at);
                        self.out.map.entry(key(&owned(path))).or_insert((line, col));
                    }
                    self.ws();
                    self.i += 1; // ':'
                    self.value(path);
                    path.pop();
                }
            }
            Some(b'[') => {
                self.i += 1;
                let mut n = 0usize;
                loop {
                    self.ws();
                    match self.b.get(self.i) {
                        Some(b']') | None => {
                            self.i += 1;
                            return;
                        }
                        Some(b',') => {
                            self.i += 1;
                            continue;
                        }
                        _ => {}
                    }
                    path.push(Item::Index(n));
                    if self.positions {
                        let col = self.column(self.line_start, self.i);
                        self.out
                            .map
                            .entry(key(&owned(path)))
                            .or_insert((self.line, col));
                    }
                    self.value(path);
                    path.pop();
                    n += 1;
                }
            }
            Some(b'"') => {
                self.raw_string();
            }
            Some(_) => {
                while let Some(&c) = self.b.get(self.i) {
                    if matches!(c, b',' | b'}' | b']' | b' ' | b'\n' | b'\r' | b'\t') {
                        break;
                    }
                    self.i += 1;
                }
            }
            None => {}
        }
    }
}

/// Scans text that serde_json has already accepted. With `positions` false only duplicate
/// keys are found (and located); that pass allocates almost nothing, so it runs on every load,
/// while the full index is built only when a diagnostic needs a line.
pub(crate) fn scan(text: &str, positions: bool) -> Locations {
    let mut s = Scanner {
        b: text.as_bytes(),
        i: 0,
        line: 1,
        line_start: 0,
        out: Locations::default(),
        positions,
        seen: Vec::new(),
        depth: 0,
    };
    s.value(&mut Vec::new());
    s.out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_keys_and_duplicates() {
        let text = "{\n  \"nodes\": {\n    \"a\": {\"type\": \"x\"},\n    \"a\": {\"type\": \"y\"}\n  },\n  \"l\": [1,\n 2]\n}";
        let loc = scan(text, true);
        assert_eq!(scan(text, false).duplicates, loc.duplicates);
        let p = |s: &[&str]| s.iter().map(|x| x.to_string()).collect::<Vec<_>>();
        assert_eq!(loc.find(&p(&["nodes", "a", "type"])), Some((3, 11)));
        assert_eq!(loc.duplicates, vec![(p(&["nodes", "a"]), 4, 5)]);
        assert_eq!(loc.find(&p(&["l", "1"])), Some((7, 2)));
        // Unknown tails fall back to the deepest known prefix.
        assert_eq!(loc.find(&p(&["nodes", "zz"])), Some((2, 3)));
    }
}
