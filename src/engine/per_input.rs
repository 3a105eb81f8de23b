//! A several-input model's fields one entry per input in the JSON users read (`fit --json`,
//! Python's `fit`): `nb`, `nf`, `delay` lists, `b`, `f`, `b_std`, `f_std` lists of lists. The
//! fits keep them flat in theta's order ([`crate::estimate::flat_parts`]); one input's JSON is
//! left exactly as it is.

use crate::oe::Structure;
use serde_json::{Map, Value};

/// Rewrites the per-input fields of `obj` (and of the objects under `nested`, e.g. a report's
/// least-squares fit) for a several-input `s`; nothing for one input.
pub fn split_fields(s: &Structure, obj: &mut Map<String, Value>, nested: &[&str]) {
    if s.m() == 1 {
        return;
    }
    let ints = |f: fn(&crate::oe::Orders) -> usize| Value::from(s.inputs().iter().map(f).collect::<Vec<_>>());
    for (key, v) in [("nb", ints(|o| o.nb)), ("nf", ints(|o| o.nf)), ("delay", ints(|o| o.delay))] {
        if obj.contains_key(key) {
            obj.insert(key.into(), v);
        }
    }
    for key in ["b", "b_std"] {
        if let Some(Value::Array(flat)) = obj.get(key) {
            let split = s.split_b(flat);
            obj.insert(key.into(), Value::from(split));
        }
    }
    for key in ["f", "f_std"] {
        if let Some(Value::Array(flat)) = obj.get(key) {
            let split = s.split_f(flat);
            obj.insert(key.into(), Value::from(split));
        }
    }
    for key in nested {
        if let Some(Value::Object(inner)) = obj.get_mut(*key) {
            split_fields(s, inner, &[]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::oe::Orders;

    #[test]
    fn several_inputs_get_one_entry_per_input_and_one_input_is_untouched() {
        let two = Structure::new(&[Orders { nb: 2, nf: 1, delay: 1 }, Orders { nb: 1, nf: 2, delay: 0 }]).unwrap();
        let doc = serde_json::json!({"nb": 2, "nf": 1, "delay": 1, "b": [1.0, 2.0, 3.0], "f": [4.0, 5.0, 6.0],
            "b_std": [0.1, 0.2, 0.3], "ls": {"nb": 2, "b": [1.0, 2.0, 3.0]}});
        let mut obj = doc.as_object().unwrap().clone();
        split_fields(&two, &mut obj, &["ls"]);
        let got = Value::Object(obj);
        assert_eq!(got["nb"], serde_json::json!([2, 1]));
        assert_eq!(got["delay"], serde_json::json!([1, 0]));
        assert_eq!(got["b"], serde_json::json!([[1.0, 2.0], [3.0]]));
        assert_eq!(got["f"], serde_json::json!([[4.0], [5.0, 6.0]]));
        assert_eq!(got["b_std"], serde_json::json!([[0.1, 0.2], [0.3]]));
        assert_eq!(got["ls"]["b"], serde_json::json!([[1.0, 2.0], [3.0]]));
        let mut one = doc.as_object().unwrap().clone();
        split_fields(&Structure::siso(2, 1, 1), &mut one, &["ls"]);
        assert_eq!(Value::Object(one), doc);
    }
}
