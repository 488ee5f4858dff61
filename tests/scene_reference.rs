//! `docs/scene-reference.md` documents exactly the keys a scene file accepts: every key the scene types
//! deserialize is a row of the reference, and every row of the reference is a key they deserialize.
//!
//! # How the accepted keys are found
//!
//! From the types, starting at [`Scene`] alone: a small self-describing [`Deserializer`] (the [`Val`] trees below)
//! feeds `Scene::deserialize` a probe document, and a custom error type records what serde's generated code
//! reports about it through the [`serde::de::Error`] hooks, which carry the types' own constant lists:
//!
//! - a table at some path given only an unknown key (`{ PROBE = () }`) fails with `unknown_field(PROBE, FIELDS)`:
//!   `FIELDS` are that table's keys (every scene table denies unknown fields; one that does not is reported);
//! - an internally tagged table (`[material]`, `[[light]]`, `[[shape]]`, `hair.procedural`) given the same fails
//!   with `missing_field(tag)`; given `tag = PROBE` it fails with `unknown_variant(PROBE, VARIANTS)`; each variant
//!   is then probed like a table, with its tag set;
//! - a value that is not a table fails with `invalid_type` for a table, and again for an array holding one (an
//!   array of tables, `[[light]]`, does not): a leaf. (A string-valued enum inside a tagged table reads the probe
//!   table as `{ variant = value }` and answers `unknown_variant` instead: a leaf as well.)
//!
//! The exploration recurses into every table-valued key, so nested tables (`[shadows.deep_opacity]`) and the
//! fields of enum variants are covered, and nothing is listed by hand.
//!
//! Why not `serde-reflection`: it traces through `deserialize_struct`/`deserialize_enum` but refuses
//! `deserialize_any`, which is how serde deserializes internally tagged enums (`#[serde(tag = "model")]`) — the
//! material models, lights, shapes and procedural models, whose variant fields are then read from serde's private
//! buffered content, out of reach of any tracing deserializer. The probe reaches them because that buffered
//! content reports its errors through the error type of the deserializer that fed it, i.e. ours.
//!
//! # How the documented keys are read
//!
//! A row of a Markdown table whose first cell is a backticked dotted key (`` `material.beta_1` ``) documents that
//! key. The nearest heading above it gives the variant: each backticked `tag = "variant"` in the heading (e.g.
//! `` ### `[material]`, `model = "marschner"` ``) qualifies the rows below it. A tag key itself
//! (`material.model`) is documented under a heading without that qualifier.
//!
//! The test also parses the reference's first TOML block as a scene, so its example stays valid.

use std::collections::BTreeSet;
use std::fmt;
use std::path::Path;

use serde::de::{self, DeserializeSeed, Deserializer, MapAccess, SeqAccess, Visitor};
use serde::Deserialize;

use cuticle::scene::Scene;

/// The unknown key and variant name put where a table is probed (no scene key starts with a control character).
const PROBE: &str = "\u{1}probe";

/// A value of a probe document: just enough of TOML's data model to build the paths to a table.
#[derive(Debug, Clone)]
enum Val {
    Unit,
    Str(String),
    Seq(Vec<Val>),
    Map(Vec<(String, Val)>),
}

/// What serde reported about a probe document.
#[derive(Debug)]
enum Probe {
    /// The probed table's keys (`unknown_field` of the probe key).
    Fields(&'static [&'static str]),
    /// An internally tagged enum's tag key (`missing_field`).
    MissingField(&'static str),
    /// The variants of the enum (`unknown_variant` of the probe variant).
    Variants(&'static [&'static str]),
    /// A value that is not a table (`invalid_type`, or a length or value error of a leaf).
    NotATable(String),
    /// Anything else.
    Other(String),
}

impl fmt::Display for Probe {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Probe::Fields(fields) => write!(f, "a table with keys {fields:?}"),
            Probe::MissingField(key) => write!(f, "missing key `{key}`"),
            Probe::Variants(names) => write!(f, "an enum of {names:?}"),
            Probe::NotATable(message) | Probe::Other(message) => f.write_str(message),
        }
    }
}

impl std::error::Error for Probe {}

impl de::Error for Probe {
    fn custom<T: fmt::Display>(msg: T) -> Self {
        Probe::Other(msg.to_string())
    }
    fn invalid_type(unexp: de::Unexpected, exp: &dyn de::Expected) -> Self {
        Probe::NotATable(format!("invalid type: {unexp}, expected {exp}"))
    }
    fn invalid_value(unexp: de::Unexpected, exp: &dyn de::Expected) -> Self {
        Probe::NotATable(format!("invalid value: {unexp}, expected {exp}"))
    }
    fn invalid_length(len: usize, exp: &dyn de::Expected) -> Self {
        Probe::NotATable(format!("invalid length {len}, expected {exp}"))
    }
    fn unknown_field(field: &str, expected: &'static [&'static str]) -> Self {
        if field == PROBE {
            Probe::Fields(expected)
        } else {
            Probe::Other(format!("unknown field {field:?}"))
        }
    }
    fn missing_field(field: &'static str) -> Self {
        Probe::MissingField(field)
    }
    fn unknown_variant(variant: &str, expected: &'static [&'static str]) -> Self {
        if variant == PROBE {
            Probe::Variants(expected)
        } else {
            Probe::Other(format!("unknown variant {variant:?}"))
        }
    }
}

/// [`Val`] as a self-describing deserializer, like a parsed TOML document.
struct ValDe(Val);

impl<'de> Deserializer<'de> for ValDe {
    type Error = Probe;

    fn deserialize_any<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Probe> {
        match self.0 {
            Val::Unit => visitor.visit_unit(),
            Val::Str(s) => visitor.visit_string(s),
            Val::Seq(items) => visitor.visit_seq(Items(items.into_iter())),
            Val::Map(entries) => visitor.visit_map(Entries {
                entries: entries.into_iter(),
                value: None,
            }),
        }
    }

    fn deserialize_option<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Probe> {
        match self.0 {
            Val::Unit => visitor.visit_none(),
            other => visitor.visit_some(ValDe(other)),
        }
    }

    serde::forward_to_deserialize_any! {
        bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string bytes byte_buf unit unit_struct
        newtype_struct seq tuple tuple_struct map struct enum identifier ignored_any
    }
}

struct Items(std::vec::IntoIter<Val>);

impl<'de> SeqAccess<'de> for Items {
    type Error = Probe;
    fn next_element_seed<T: DeserializeSeed<'de>>(
        &mut self,
        seed: T,
    ) -> Result<Option<T::Value>, Probe> {
        self.0
            .next()
            .map(|v| seed.deserialize(ValDe(v)))
            .transpose()
    }
}

struct Entries {
    entries: std::vec::IntoIter<(String, Val)>,
    value: Option<Val>,
}

impl<'de> MapAccess<'de> for Entries {
    type Error = Probe;
    fn next_key_seed<K: DeserializeSeed<'de>>(
        &mut self,
        seed: K,
    ) -> Result<Option<K::Value>, Probe> {
        match self.entries.next() {
            Some((key, value)) => {
                self.value = Some(value);
                seed.deserialize(ValDe(Val::Str(key))).map(Some)
            }
            None => Ok(None),
        }
    }
    fn next_value_seed<V: DeserializeSeed<'de>>(&mut self, seed: V) -> Result<V::Value, Probe> {
        seed.deserialize(ValDe(self.value.take().expect("a key before its value")))
    }
}

/// One step from the document root to a probed value.
#[derive(Debug, Clone)]
enum Step {
    /// The value of `key` in the current table; `tag` is the variant the table is set to, if it is tagged.
    Key {
        tag: Option<(String, String)>,
        key: String,
    },
    /// The single element of an array.
    Elem,
}

/// The probe document with `leaf` at the end of `path`.
fn document(path: &[Step], leaf: Val) -> Val {
    match path.split_first() {
        None => leaf,
        Some((Step::Elem, rest)) => Val::Seq(vec![document(rest, leaf)]),
        Some((Step::Key { tag, key }, rest)) => {
            let mut entries = Vec::new();
            if let Some((tag, variant)) = tag {
                entries.push((tag.clone(), Val::Str(variant.clone())));
            }
            entries.push((key.clone(), document(rest, leaf)));
            Val::Map(entries)
        }
    }
}

/// A table at the end of `path` holding `entries` (and the tag `tag`, if set).
fn table(tag: Option<&(String, String)>, entries: Vec<(String, Val)>) -> Val {
    let mut all: Vec<(String, Val)> = tag
        .map(|(t, v)| (t.clone(), Val::Str(v.clone())))
        .into_iter()
        .collect();
    all.extend(entries);
    Val::Map(all)
}

/// Deserializes a [`Scene`] from the probe document and returns what serde reported.
fn probe(path: &[Step], leaf: Val) -> Probe {
    match Scene::deserialize(ValDe(document(path, leaf))) {
        Ok(_) => Probe::Other("accepted".into()),
        Err(e) => e,
    }
}

/// A key as the reference names it: the dotted path, then the variants it belongs to, e.g.
/// `material.beta_1 (model = "marschner")`.
fn key_name(dotted: &[String], variants: &[String]) -> String {
    if variants.is_empty() {
        dotted.join(".")
    } else {
        format!("{} ({})", dotted.join("."), variants.join(", "))
    }
}

/// Collects the keys of the table reached by `path` (set to `tag`, if tagged) into `out`, recursing into the
/// table-valued ones. `dotted` and `variants` name the table as the reference does.
fn explore_table(
    path: &[Step],
    tag: Option<(String, String)>,
    dotted: &[String],
    variants: &[String],
    out: &mut BTreeSet<String>,
    problems: &mut Vec<String>,
) {
    let fields = match probe(path, table(tag.as_ref(), vec![(PROBE.into(), Val::Unit)])) {
        Probe::Fields(fields) => fields,
        other => {
            problems.push(format!(
                "{}: not a table that denies unknown keys: {other}",
                key_name(dotted, variants)
            ));
            return;
        }
    };
    for &field in fields {
        let mut dotted = dotted.to_vec();
        dotted.push(field.to_owned());
        out.insert(key_name(&dotted, variants));
        let mut path = path.to_vec();
        path.push(Step::Key {
            tag: tag.clone(),
            key: field.to_owned(),
        });
        explore_value(&path, &dotted, variants, out, problems);
    }
}

/// Collects the keys below the value at `path`: a table, a tagged table, an array of either, or a leaf.
fn explore_value(
    path: &[Step],
    dotted: &[String],
    variants: &[String],
    out: &mut BTreeSet<String>,
    problems: &mut Vec<String>,
) {
    match probe(path, table(None, vec![(PROBE.into(), Val::Unit)])) {
        Probe::Fields(_) => explore_table(path, None, dotted, variants, out, problems),
        Probe::MissingField(tag) => {
            let set = table(None, vec![(tag.into(), Val::Str(PROBE.into()))]);
            let Probe::Variants(names) = probe(path, set) else {
                problems.push(format!(
                    "{}: missing `{tag}`, but `{tag}` does not name variants",
                    key_name(dotted, variants)
                ));
                return;
            };
            let mut tag_key = dotted.to_vec();
            tag_key.push(tag.to_owned());
            out.insert(key_name(&tag_key, variants));
            for &name in names {
                let mut variants = variants.to_vec();
                variants.push(format!("{tag} = \"{name}\""));
                let tag = Some((tag.to_owned(), name.to_owned()));
                explore_table(path, tag, dotted, &variants, out, problems);
            }
        }
        Probe::NotATable(_) if !matches!(path.last(), Some(Step::Elem)) => {
            let mut elem = path.to_vec();
            elem.push(Step::Elem);
            if !matches!(
                probe(&elem, table(None, vec![(PROBE.into(), Val::Unit)])),
                Probe::NotATable(_)
            ) {
                explore_value(&elem, dotted, variants, out, problems);
            }
        }
        // A string-valued enum (`sampling = "uniform"`) read from serde's buffered content (inside a tagged
        // table) takes a one-key table as `{ variant = value }`, and names its variants: a leaf too.
        Probe::NotATable(_) | Probe::Variants(_) => {}
        other => problems.push(format!(
            "{}: unexpected answer to a probe: {other}",
            key_name(dotted, variants)
        )),
    }
}

/// Every key a scene file accepts, named as the reference names them.
fn accepted_keys() -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    let mut problems = Vec::new();
    explore_table(&[], None, &[], &[], &mut out, &mut problems);
    assert!(
        problems.is_empty(),
        "probing the scene types: {problems:#?}"
    );
    out
}

fn reference() -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/scene-reference.md");
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The backticked spans of a line.
fn code_spans(line: &str) -> Vec<&str> {
    line.split('`').skip(1).step_by(2).collect()
}

/// Every key the reference documents, named as [`accepted_keys`] names them.
fn documented_keys(text: &str) -> BTreeSet<String> {
    let mut variants: Vec<String> = Vec::new();
    let mut out = BTreeSet::new();
    let mut in_code = false;
    for line in text.lines() {
        let line = line.trim();
        if line.starts_with("```") {
            in_code = !in_code;
            continue;
        }
        if in_code {
            continue;
        }
        if line.starts_with('#') {
            variants = code_spans(line)
                .into_iter()
                .filter(|s| s.contains(" = \""))
                .map(str::to_owned)
                .collect();
            continue;
        }
        let Some(row) = line.strip_prefix('|') else {
            continue;
        };
        let first = row.split('|').next().unwrap_or("").trim();
        let is_key = |s: &str| {
            !s.is_empty()
                && s.chars()
                    .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_' || c == '.')
        };
        if let Some(key) = first
            .strip_prefix('`')
            .and_then(|s| s.strip_suffix('`'))
            .filter(|s| is_key(s))
        {
            let dotted: Vec<String> = key.split('.').map(str::to_owned).collect();
            out.insert(key_name(&dotted, &variants));
        }
    }
    out
}

#[test]
fn the_reference_documents_exactly_the_accepted_keys() {
    let accepted = accepted_keys();
    // The probe reaches into every kind of table: a plain one, a nested one, tagged ones and arrays of them.
    for key in [
        "hair.radius_scale",
        "shadows.deep_opacity.bias",
        "material.model",
        "material.beta_1 (model = \"marschner\")",
        "material.beta_m (model = \"chiang\")",
        "light.kind",
        "light.angular_radius (kind = \"distant\")",
        "shape.open (kind = \"box\")",
        "hair.procedural.clumps (kind = \"wavy-patch\")",
    ] {
        assert!(
            accepted.contains(key),
            "the probe missed {key}: {accepted:#?}"
        );
    }
    let documented = documented_keys(&reference());
    let undocumented: Vec<&String> = accepted.difference(&documented).collect();
    let unknown: Vec<&String> = documented.difference(&accepted).collect();
    assert!(
        undocumented.is_empty() && unknown.is_empty(),
        "docs/scene-reference.md is out of date.\n\
         Keys a scene accepts that the reference does not document ({}):\n  {}\n\
         Keys the reference documents that no scene accepts ({}):\n  {}",
        undocumented.len(),
        join(&undocumented),
        unknown.len(),
        join(&unknown),
    );
}

fn join(keys: &[&String]) -> String {
    if keys.is_empty() {
        "(none)".into()
    } else {
        keys.iter()
            .map(|k| k.as_str())
            .collect::<Vec<_>>()
            .join("\n  ")
    }
}

#[test]
fn the_reference_example_is_a_valid_scene() {
    let text = reference();
    let start = text
        .find("```toml\n")
        .expect("the reference starts with a ```toml example")
        + "```toml\n".len();
    let end = start
        + text[start..]
            .find("```")
            .expect("the example's closing fence");
    let base = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    Scene::parse(
        &text[start..end],
        Path::new("docs/scene-reference.md"),
        &base,
    )
    .unwrap_or_else(|e| panic!("the reference's example scene: {e}"));
}
