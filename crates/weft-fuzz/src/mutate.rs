//! Mutations: how a valid input becomes a case.
//!
//! Most mutations are structure-aware (they parse the graph file and change one thing a user
//! could plausibly change: a number, a node's type, a parameter moved to another node, a
//! connection, a deleted key), because random bytes mostly stop at the JSON parser. A share of
//! cases are byte-level (cuts, junk, duplicated ranges) so the parser and the line locator are
//! fuzzed too. OBJ files are mutated line by line (numbers, indices, junk lines, truncation).
//! Every case is a pure function of (seed, case index), so any case can be regenerated.

use serde_json::Value as Json;

/// One input set: a graph file and the files it reads, by name.
#[derive(Clone, Debug)]
pub struct Seed {
    /// Where it came from (file name).
    pub name: String,
    /// The graph file's text.
    pub graph: String,
    /// Other files beside it (OBJ meshes), name → bytes.
    pub files: Vec<(String, Vec<u8>)>,
}

/// A mutated input: what the worker writes to a fresh directory and runs.
#[derive(Clone, Debug)]
pub struct Case {
    /// The seed it came from.
    pub origin: String,
    /// The mutations applied, in order, in words.
    pub mutations: Vec<String>,
    /// The graph file's text (`graph.json`).
    pub graph: String,
    /// Other files, name → bytes.
    pub files: Vec<(String, Vec<u8>)>,
}

/// Generates cases from seeds.
pub struct Mutator {
    types: Vec<String>,
    dictionary: Vec<String>,
    /// Per seed, the running total of the seeds' weights (see [`CONTACT_WEIGHT`]).
    weights: Vec<u64>,
}

/// How much more often a seed with contacts (a collision group) is drawn than another:
/// contact scenes have the most parameters that size the work (thicknesses, meshes, their
/// distances) and the fewest seeds, and the inputs that ran them for minutes without a word
/// (issue 70) were found there.
pub const CONTACT_WEIGHT: u64 = 3;

/// A seed's weight in the draw.
fn weight(s: &Seed) -> u64 {
    if s.graph.contains("convert.collision_group") {
        CONTACT_WEIGHT
    } else {
        1
    }
}

const NUMBERS: [f64; 22] = [
    0.0,
    -1.0,
    1.0,
    2.0,
    3.0,
    0.5,
    -0.5,
    1e-12,
    1e-300,
    1e9,
    1e18,
    1e300,
    -1e300,
    4096.0,
    65536.0,
    1e6,
    2147483648.0,
    9007199254740992.0,
    9.2e18,
    255.0,
    10000.0,
    -4096.0,
];

const OBJ_TOKENS: [&str; 14] = [
    "nan",
    "inf",
    "-inf",
    "0",
    "-0",
    "1e308",
    "-1",
    "-99",
    "999999",
    "4294967296",
    "1.5",
    "x",
    "",
    "1/2/3",
];

const OBJ_LINES: [&str; 12] = [
    "f 1",
    "f 1 1 1",
    "v 1 2",
    "v nan 0 0",
    "f 1 2 3 4 5 6 7 8",
    "f -1 -2 -3",
    "f 0 1 2",
    "vt 0 0",
    "o other",
    "f 1/1/1 2//2 3/3",
    "\u{0}\u{1}",
    "g",
];

impl Mutator {
    /// A mutator knowing the registry's node type names (a type swap should often land on a
    /// real type) and the strings of the seeds (ports, ids, enum values).
    pub fn new(seeds: &[Seed], types: Vec<String>) -> Self {
        let mut dictionary: Vec<String> = vec![
            String::new(),
            "../escape".into(),
            "/tmp/weft-fuzz-abs".into(),
            "a".repeat(300),
            "nan".into(),
            "node.port".into(),
            ".".into(),
            "in.x".into(),
            "∂ü".into(),
            "all".into(),
        ];
        for s in seeds {
            if let Ok(j) = serde_json::from_str::<Json>(&s.graph) {
                collect_strings(&j, &mut dictionary);
            }
        }
        dictionary.extend(types.iter().cloned());
        dictionary.sort();
        dictionary.dedup();
        let weights = seeds
            .iter()
            .scan(0, |total, s| {
                *total += weight(s);
                Some(*total)
            })
            .collect();
        Mutator {
            types,
            dictionary,
            weights,
        }
    }

    /// The case for index `index` of a run seeded by `seed`.
    pub fn case(&self, seeds: &[Seed], seed: u64, index: u64) -> Case {
        let mut rng = fastrand::Rng::with_seed(
            seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ index.wrapping_mul(0xD1B5_4A32_D192_ED03),
        );
        let total = self.weights.last().copied().unwrap_or(0);
        let s = match total {
            0 => &seeds[rng.usize(..seeds.len())],
            _ => {
                let r = rng.u64(..total);
                &seeds[self
                    .weights
                    .partition_point(|&w| w <= r)
                    .min(seeds.len() - 1)]
            }
        };
        let mut case = Case {
            origin: s.name.clone(),
            mutations: Vec::new(),
            graph: s.graph.clone(),
            files: s.files.clone(),
        };
        let n = 1 + rng.usize(..4);
        for _ in 0..n {
            let m = if !case.files.is_empty() && rng.f64() < 0.3 {
                let k = rng.usize(..case.files.len());
                let (name, bytes) = &mut case.files[k];
                format!("{name}: {}", mutate_obj(&mut rng, bytes))
            } else if rng.f64() < 0.15 {
                mutate_bytes(&mut rng, &mut case.graph)
            } else {
                match serde_json::from_str::<Json>(&case.graph) {
                    Ok(mut j) => {
                        let m = self.mutate_json(&mut rng, &mut j);
                        case.graph =
                            serde_json::to_string_pretty(&j).unwrap_or_else(|_| case.graph.clone());
                        m
                    }
                    Err(_) => mutate_bytes(&mut rng, &mut case.graph),
                }
            };
            case.mutations.push(m);
        }
        case
    }

    fn mutate_json(&self, rng: &mut fastrand::Rng, j: &mut Json) -> String {
        for _ in 0..8 {
            let m = match rng.usize(..10) {
                0..=2 => self.tweak_number(rng, j),
                3 => self.swap_string(rng, j),
                4 => move_param(rng, j),
                5 => self.change_type(rng, j),
                6 => delete_entry(rng, j),
                7 => duplicate_node(rng, j),
                8 => rewire(rng, j),
                _ => change_kind(rng, j),
            };
            if let Some(m) = m {
                return m;
            }
        }
        "no applicable mutation".into()
    }

    fn tweak_number(&self, rng: &mut fastrand::Rng, j: &mut Json) -> Option<String> {
        let paths = paths_where(j, &|v| v.is_number());
        let p = pick(rng, &paths)?.clone();
        let v = at_mut(j, &p)?;
        let x = v.as_f64().unwrap_or(0.0);
        let y = match rng.usize(..4) {
            0 => x * [2.0, 10.0, 1000.0, 1e-3, -1.0][rng.usize(..5)],
            1 => x + 1.0,
            _ => NUMBERS[rng.usize(..NUMBERS.len())],
        };
        *v = if y.fract() == 0.0 && y.abs() < 9e15 && rng.bool() {
            Json::from(y as i64)
        } else {
            serde_json::Number::from_f64(y).map_or(Json::Null, Json::Number)
        };
        Some(format!("{}: {x} -> {y}", show(&p)))
    }

    fn swap_string(&self, rng: &mut fastrand::Rng, j: &mut Json) -> Option<String> {
        let paths = paths_where(j, &|v| v.is_string());
        let p = pick(rng, &paths)?.clone();
        let new = pick(rng, &self.dictionary)?.clone();
        let v = at_mut(j, &p)?;
        let old = std::mem::replace(v, Json::String(new.clone()));
        Some(format!("{}: {old} -> {new:?}", show(&p)))
    }

    fn change_type(&self, rng: &mut fastrand::Rng, j: &mut Json) -> Option<String> {
        let nodes = j.get_mut("nodes")?.as_object_mut()?;
        let ids: Vec<String> = nodes.keys().cloned().collect();
        let a = pick(rng, &ids)?.clone();
        if rng.bool() && ids.len() > 1 {
            let b = pick(rng, &ids)?.clone();
            let ta = nodes.get(&a)?.get("type")?.clone();
            let tb = nodes.get(&b)?.get("type")?.clone();
            *nodes.get_mut(&a)?.get_mut("type")? = tb;
            *nodes.get_mut(&b)?.get_mut("type")? = ta;
            Some(format!("swap the types of '{a}' and '{b}'"))
        } else {
            let t = pick(rng, &self.types)?.clone();
            *nodes
                .get_mut(&a)?
                .as_object_mut()?
                .entry("type")
                .or_insert(Json::Null) = Json::String(t.clone());
            Some(format!("node '{a}' becomes a '{t}'"))
        }
    }
}

/// A path into a JSON tree: object keys and array indices.
#[derive(Clone, Debug)]
enum Seg {
    Key(String),
    Index(usize),
}

fn show(p: &[Seg]) -> String {
    p.iter()
        .map(|s| match s {
            Seg::Key(k) => k.clone(),
            Seg::Index(i) => i.to_string(),
        })
        .collect::<Vec<_>>()
        .join(".")
}

fn paths_where(j: &Json, keep: &dyn Fn(&Json) -> bool) -> Vec<Vec<Seg>> {
    fn walk(j: &Json, at: &mut Vec<Seg>, keep: &dyn Fn(&Json) -> bool, out: &mut Vec<Vec<Seg>>) {
        if keep(j) {
            out.push(at.clone());
        }
        match j {
            Json::Object(m) => {
                for (k, v) in m {
                    at.push(Seg::Key(k.clone()));
                    walk(v, at, keep, out);
                    at.pop();
                }
            }
            Json::Array(a) => {
                for (i, v) in a.iter().enumerate() {
                    at.push(Seg::Index(i));
                    walk(v, at, keep, out);
                    at.pop();
                }
            }
            _ => {}
        }
    }
    let mut out = Vec::new();
    walk(j, &mut Vec::new(), keep, &mut out);
    out
}

fn at_mut<'a>(j: &'a mut Json, p: &[Seg]) -> Option<&'a mut Json> {
    let mut v = j;
    for s in p {
        v = match s {
            Seg::Key(k) => v.get_mut(k.as_str())?,
            Seg::Index(i) => v.get_mut(*i)?,
        };
    }
    Some(v)
}

fn pick<'a, T>(rng: &mut fastrand::Rng, v: &'a [T]) -> Option<&'a T> {
    (!v.is_empty()).then(|| &v[rng.usize(..v.len())])
}

fn collect_strings(j: &Json, out: &mut Vec<String>) {
    match j {
        Json::String(s) => out.push(s.clone()),
        Json::Object(m) => {
            for (k, v) in m {
                out.push(k.clone());
                collect_strings(v, out);
            }
        }
        Json::Array(a) => a.iter().for_each(|v| collect_strings(v, out)),
        _ => {}
    }
}

fn node_ids(j: &Json) -> Vec<String> {
    j.get("nodes")
        .and_then(|n| n.as_object())
        .map(|m| m.keys().cloned().collect())
        .unwrap_or_default()
}

/// Moves one parameter from a node to another (often one whose type lacks it).
fn move_param(rng: &mut fastrand::Rng, j: &mut Json) -> Option<String> {
    let ids = node_ids(j);
    let with: Vec<String> = ids
        .iter()
        .filter(|id| {
            j["nodes"][id.as_str()]
                .get("params")
                .and_then(|p| p.as_object())
                .is_some_and(|p| !p.is_empty())
        })
        .cloned()
        .collect();
    let a = pick(rng, &with)?.clone();
    let b = pick(rng, &ids)?.clone();
    let params = j["nodes"][a.as_str()]["params"].as_object_mut()?;
    let keys: Vec<String> = params.keys().cloned().collect();
    let k = pick(rng, &keys)?.clone();
    let v = params.remove(&k)?;
    let target = j["nodes"][b.as_str()].as_object_mut()?;
    let tp = target
        .entry("params")
        .or_insert_with(|| Json::Object(Default::default()));
    tp.as_object_mut()?.insert(k.clone(), v);
    Some(format!("move param '{k}' from '{a}' to '{b}'"))
}

fn delete_entry(rng: &mut fastrand::Rng, j: &mut Json) -> Option<String> {
    let paths = paths_where(j, &|v| v.is_object() || v.is_array());
    let p = pick(rng, &paths)?.clone();
    let v = at_mut(j, &p)?;
    match v {
        Json::Object(m) if !m.is_empty() => {
            let keys: Vec<String> = m.keys().cloned().collect();
            let k = pick(rng, &keys)?.clone();
            m.remove(&k);
            Some(format!("delete {}.{k}", show(&p)))
        }
        Json::Array(a) if !a.is_empty() => {
            let i = rng.usize(..a.len());
            a.remove(i);
            Some(format!("delete {}.{i}", show(&p)))
        }
        _ => None,
    }
}

fn duplicate_node(rng: &mut fastrand::Rng, j: &mut Json) -> Option<String> {
    let ids = node_ids(j);
    let a = pick(rng, &ids)?.clone();
    let nodes = j.get_mut("nodes")?.as_object_mut()?;
    let copy = nodes.get(&a)?.clone();
    let new = format!("{a}_copy");
    nodes.insert(new.clone(), copy);
    Some(format!("duplicate node '{a}' as '{new}'"))
}

/// Points one input (or output) at another connection's source, or at a made-up port.
fn rewire(rng: &mut fastrand::Rng, j: &mut Json) -> Option<String> {
    let refs = paths_where(j, &|v| v.as_str().is_some_and(|s| s.contains('.')));
    let p = pick(rng, &refs)?.clone();
    let sources: Vec<String> = refs
        .iter()
        .filter_map(|q| {
            let mut jj = j.clone();
            at_mut(&mut jj, q).and_then(|v| v.as_str().map(str::to_string))
        })
        .collect();
    let new = if rng.f64() < 0.8 {
        pick(rng, &sources)?.clone()
    } else {
        let ids = node_ids(j);
        format!(
            "{}.{}",
            pick(rng, &ids)?,
            ["out", "element", "scene", "state", "x"][rng.usize(..5)]
        )
    };
    let v = at_mut(j, &p)?;
    let old = std::mem::replace(v, Json::String(new.clone()));
    Some(format!("rewire {}: {old} -> {new}", show(&p)))
}

fn change_kind(rng: &mut fastrand::Rng, j: &mut Json) -> Option<String> {
    let paths = paths_where(j, &|_| true);
    let p = pick(rng, &paths)?.clone();
    if p.is_empty() {
        return None;
    }
    let v = at_mut(j, &p)?;
    let new = match rng.usize(..7) {
        0 => Json::Null,
        1 => Json::Bool(rng.bool()),
        2 => Json::from(rng.i64(-3..100_000)),
        3 => Json::String("x".into()),
        4 => serde_json::json!([1, 2, 3]),
        5 => serde_json::json!({}),
        _ => serde_json::json!([[0.0, 1.0], "a", null]),
    };
    *v = new.clone();
    Some(format!("{} becomes {new}", show(&p)))
}

/// Byte-level damage to the graph text (kept valid UTF-8 so it can be stored as a string).
fn mutate_bytes(rng: &mut fastrand::Rng, text: &mut String) -> String {
    let mut b = text.clone().into_bytes();
    let at = rng.usize(..=b.len());
    let m = match rng.usize(..4) {
        0 => {
            let len = rng.usize(..=64.min(b.len() - at));
            b.drain(at..at + len);
            format!("cut {len} bytes at {at}")
        }
        1 => {
            let junk = [
                "}", "{", "]", "[", ",", "\"", ":", "NaN", "1e999", "-", "\\u0000", "null", "\n",
            ][rng.usize(..13)];
            b.splice(at..at, junk.bytes());
            format!("insert {junk:?} at {at}")
        }
        2 => {
            let len = rng.usize(..=200.min(b.len() - at));
            let copy = b[at..at + len].to_vec();
            let to = rng.usize(..=b.len());
            b.splice(to..to, copy);
            format!("copy {len} bytes from {at} to {to}")
        }
        _ => {
            b.truncate(at);
            format!("truncate at {at}")
        }
    };
    *text = String::from_utf8_lossy(&b).into_owned();
    m
}

/// Line-level damage to an OBJ file.
fn mutate_obj(rng: &mut fastrand::Rng, bytes: &mut Vec<u8>) -> String {
    let text = String::from_utf8_lossy(bytes).into_owned();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    if lines.is_empty() {
        lines.push(String::new());
    }
    let i = rng.usize(..lines.len());
    let m = match rng.usize(..6) {
        0 => {
            lines.remove(i);
            format!("delete line {}", i + 1)
        }
        1 => {
            let l = lines[i].clone();
            lines.insert(i, l);
            format!("duplicate line {}", i + 1)
        }
        2 | 3 => {
            let mut toks: Vec<String> = lines[i].split_whitespace().map(str::to_string).collect();
            if toks.len() > 1 {
                let k = 1 + rng.usize(..toks.len() - 1);
                toks[k] = OBJ_TOKENS[rng.usize(..OBJ_TOKENS.len())].to_string();
            }
            let l = toks.join(" ");
            let m = format!("line {} -> {l:?}", i + 1);
            lines[i] = l;
            m
        }
        4 => {
            let l = OBJ_LINES[rng.usize(..OBJ_LINES.len())].to_string();
            let m = format!("insert {l:?} at line {}", i + 1);
            lines.insert(i, l);
            m
        }
        _ => {
            let n = rng.usize(..=text.len());
            *bytes = text.as_bytes()[..n].to_vec();
            return format!("truncate at byte {n}");
        }
    };
    *bytes = (lines.join("\n") + "\n").into_bytes();
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    fn seeds() -> Vec<Seed> {
        vec![Seed {
            name: "s.json".into(),
            graph: r#"{"format": "weft-graph", "version": 1,
              "nodes": {"a": {"type": "value.float", "params": {"value": 2.0}},
                        "b": {"type": "math.scale", "inputs": {"x": "a.out"}, "params": {"factor": 3}}},
              "outputs": {"y": "b.out"}}"#
                .into(),
            files: vec![("m.obj".into(), b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n".to_vec())],
        }]
    }

    #[test]
    fn cases_are_a_function_of_seed_and_index() {
        let s = seeds();
        let m = Mutator::new(&s, vec!["math.add".into()]);
        for i in 0..50 {
            let (a, b) = (m.case(&s, 7, i), m.case(&s, 7, i));
            assert_eq!(a.graph, b.graph);
            assert_eq!(a.files, b.files);
            assert_eq!(a.mutations, b.mutations);
        }
        // Different indices give different cases (almost always; 50 of 50 equal would mean
        // the index is ignored).
        let distinct: std::collections::BTreeSet<String> =
            (0..50).map(|i| m.case(&s, 7, i).graph).collect();
        assert!(distinct.len() > 25, "{}", distinct.len());
    }

    #[test]
    fn every_case_changes_something() {
        let s = seeds();
        let m = Mutator::new(&s, vec!["math.add".into()]);
        let same = (0..200)
            .filter(|&i| {
                let c = m.case(&s, 1, i);
                c.graph == s[0].graph && c.files == s[0].files
            })
            .count();
        // A mutation can be a no-op (a number replaced by itself); rarely.
        assert!(same < 10, "{same} of 200 cases were the seed itself");
    }
}
