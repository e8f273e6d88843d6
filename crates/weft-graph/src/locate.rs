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
}

impl Scanner<'_> {
    fn pos(&self) -> (usize, usize) {
        // Columns count characters, not bytes.
        let col = String::from_utf8_lossy(&self.b[self.line_start..self.i])
            .chars()
            .count()
            + 1;
        (self.line, col)
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
    fn string(&mut self) -> String {
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
        let raw = &self.b[start..self.i.min(self.b.len())];
        serde_json::from_slice::<String>(raw).unwrap_or_default()
    }
    fn value(&mut self, path: &mut Vec<String>) {
        self.ws();
        match self.b.get(self.i) {
            Some(b'{') => {
                self.i += 1;
                let mut seen = std::collections::HashSet::new();
                loop {
                    self.ws();
                    match self.b.get(self.i) {
                        Some(b'}') | None => {
                            self.i += 1;
                            return;
                        }
                        Some(b',') => {
                            self.i += 1;
                            continue;
                        }
                        _ => {}
                    }
                    let at = self.pos();
                    let k = self.string();
                    path.push(k.clone());
                    if !seen.insert(k) {
                        self.out.duplicates.push((path.clone(), at.0, at.1));
                    } else {
                        // The first occurrence wins; a duplicate's children must not move it.
                        self.out.map.entry(key(path)).or_insert(at);
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
                    path.push(n.to_string());
                    let at = self.pos();
                    self.out.map.entry(key(path)).or_insert(at);
                    self.value(path);
                    path.pop();
                    n += 1;
                }
            }
            Some(b'"') => {
                self.string();
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

/// Scans text that serde_json has already accepted.
pub(crate) fn scan(text: &str) -> Locations {
    let mut s = Scanner {
        b: text.as_bytes(),
        i: 0,
        line: 1,
        line_start: 0,
        out: Locations::default(),
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
        let loc = scan(text);
        let p = |s: &[&str]| s.iter().map(|x| x.to_string()).collect::<Vec<_>>();
        assert_eq!(loc.find(&p(&["nodes", "a", "type"])), Some((3, 11)));
        assert_eq!(loc.duplicates, vec![(p(&["nodes", "a"]), 4, 5)]);
        assert_eq!(loc.find(&p(&["l", "1"])), Some((7, 2)));
        // Unknown tails fall back to the deepest known prefix.
        assert_eq!(loc.find(&p(&["nodes", "zz"])), Some((2, 3)));
    }
}
