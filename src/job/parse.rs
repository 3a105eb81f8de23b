//! A job's JSON read into [`super::Job`] with errors a user can act on: the field at fault by its
//! path in the file (`data.u`, `data[1].rows`, `grid.k[2]`, `solver.huber_hessian`) and what the
//! field accepts, in words rather than serde's type names (`expected usize` reads "expected a
//! whole number >= 0"). The path comes from `serde_path_to_error`, which follows serde through
//! the job's types; the types whose JSON takes more than one form (`data`, `grid.k`, a column,
//! `header`, `uncertainty`) say what they accept in their own visitors, not through serde's
//! `untagged`, whose error ("data did not match any variant of untagged enum ...") names
//! neither the field nor the forms. The job file, a job given as text and a results folder's
//! `job.json` are read here alike.

use serde::de::DeserializeOwned;

/// `T` from JSON text, or the one-line message naming the field, what it accepts and where.
pub(super) fn from_text<T: DeserializeOwned>(text: &str) -> Result<T, String> {
    let mut de = serde_json::Deserializer::from_str(text);
    let value = serde_path_to_error::deserialize(&mut de).map_err(|e| message(Some(e.path()), e.inner()))?;
    de.end().map_err(|e| message(None, &e))?;
    Ok(value)
}

/// `T` from a JSON value (a `job.json` after its format fields are taken out; no positions).
pub(super) fn from_value<T: DeserializeOwned>(value: serde_json::Value) -> Result<T, String> {
    serde_path_to_error::deserialize(value).map_err(|e| message(Some(e.path()), e.inner()))
}

/// `field 'data.u': invalid type: boolean `true`, expected a column name or a 1-based column
/// index at line 3 column 20`. A syntax error has no field, nor has the job as a whole.
fn message(path: Option<&serde_path_to_error::Path>, e: &serde_json::Error) -> String {
    let text = e.to_string();
    let at = format!(" at line {} column {}", e.line(), e.column());
    let what = if e.line() > 0 { text.strip_suffix(&at).unwrap_or(&text) } else { &text };
    let what = plain_words(what);
    let at = if e.line() > 0 { at } else { String::new() };
    let field = path.map(|p| p.to_string()).filter(|p| p != "." && e.is_data());
    let msg = match field {
        Some(field) => format!("field '{field}': {what}{at}"),
        None => format!("{what}{at}"),
    };
    crate::data::one_line(&msg)
}

/// Serde's names of what a field takes (the end of its message) and the words the job's
/// reference (docs/JOBS.md) uses for them.
const PLAIN: &[(&str, &str)] = &[
    ("expected usize", "expected a whole number >= 0"),
    ("expected u64", "expected a whole number >= 0"),
    ("expected u32", "expected a whole number >= 0"),
    ("expected f64", "expected a number"),
    ("expected path string", "expected a path (a string)"),
    ("expected a sequence", "expected a list [...]"),
    ("expected an array of length 2", "expected a list of two values [a, b]"),
];

/// `msg` with serde's type names in words ([`PLAIN`]; a derived struct's `struct Name` is an
/// object) and its names of JSON values (`map`, `sequence`) as JSON calls them.
fn plain_words(msg: &str) -> String {
    let mut msg = msg.replacen("invalid type: map,", "invalid type: object,", 1);
    msg = msg.replacen("invalid type: sequence,", "invalid type: list,", 1);
    if let Some((serde, words)) = PLAIN.iter().find(|(serde, _)| msg.ends_with(serde)) {
        return format!("{}{words}", &msg[..msg.len() - serde.len()]);
    }
    // `struct Grid`, or `struct Grid with 4 elements` of a list given for it (serde would read
    // the fields by position).
    if let Some(at) = msg.rfind("expected struct ")
        && let name = msg[at + 16..].split(" with ").next().unwrap_or_default()
        && name.chars().all(|c| c.is_alphanumeric() || c == '_')
    {
        return format!("{}expected an object {{\"field\": value, ...}}", &msg[..at]);
    }
    msg
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn serde_names_become_words() {
        assert_eq!(
            plain_words("invalid type: boolean `true`, expected usize"),
            "invalid type: boolean `true`, expected a whole number >= 0"
        );
        assert_eq!(
            plain_words("invalid type: map, expected struct SolverOptions"),
            "invalid type: object, expected an object {\"field\": value, ...}"
        );
        assert_eq!(
            plain_words("invalid length 0, expected struct Grid with 4 elements"),
            "invalid length 0, expected an object {\"field\": value, ...}"
        );
        assert_eq!(plain_words("unknown field `x`"), "unknown field `x`");
    }
}
