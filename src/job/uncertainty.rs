//! The job's `uncertainty` field: how the picks' uncertainty is reported (METHOD.md 17).

use serde::{Deserialize, Serialize};

/// How the picks' uncertainty is reported (METHOD.md 17): `"local"` (the default: the
/// sandwich covariance at the fit, METHOD.md 10) or `"bootstrap"`, also written
/// `{"method": "bootstrap", "replicates": B, "seed": S}`: the bootstrap of the whole estimation
/// of each watched pick after the sweep (METHOD.md 17.3), its intervals in selection.json.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Uncertainty {
    pub method: UncertaintyMethod,
    /// B, the bootstrap's replicates (default [`crate::estimate::bootstrap::DEFAULT_REPLICATES`]).
    pub replicates: usize,
    /// The bootstrap's seed (default [`crate::estimate::bootstrap::DEFAULT_SEED`]).
    pub seed: u64,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum UncertaintyMethod {
    /// The sandwich covariance at the fit only.
    #[default]
    Local,
    /// The bootstrap of the whole estimation of the watched picks besides.
    Bootstrap,
}

crate::names::names!(UncertaintyMethod { Local = "local", Bootstrap = "bootstrap" });

impl Default for Uncertainty {
    fn default() -> Self {
        Uncertainty {
            method: UncertaintyMethod::Local,
            replicates: crate::estimate::bootstrap::DEFAULT_REPLICATES,
            seed: crate::estimate::bootstrap::DEFAULT_SEED,
        }
    }
}

impl Uncertainty {
    pub fn is_local(&self) -> bool {
        self.method == UncertaintyMethod::Local
    }
}

/// The object form of `uncertainty`, as written.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct UncertaintyObject {
    method: UncertaintyMethod,
    replicates: Option<usize>,
    seed: Option<u64>,
}

/// A name or an object, said so in the error of anything else ([`super::parse`]).
impl<'de> Deserialize<'de> for Uncertainty {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        struct Visitor;
        impl<'de> serde::de::Visitor<'de> for Visitor {
            type Value = UncertaintyObject;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("\"local\", \"bootstrap\" or {\"method\": \"bootstrap\", \"replicates\": B, \"seed\": S}")
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> std::result::Result<UncertaintyObject, E> {
                let method =
                    UncertaintyMethod::from_name(v).ok_or_else(|| E::unknown_variant(v, UncertaintyMethod::NAMES))?;
                Ok(UncertaintyObject { method, replicates: None, seed: None })
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(
                self,
                map: A,
            ) -> std::result::Result<UncertaintyObject, A::Error> {
                let o = UncertaintyObject::deserialize(serde::de::value::MapAccessDeserializer::new(map))?;
                if o.method == UncertaintyMethod::Local && (o.replicates.is_some() || o.seed.is_some()) {
                    return Err(serde::de::Error::custom(
                        "'replicates' and 'seed' are settings of the method \"bootstrap\"",
                    ));
                }
                Ok(o)
            }
        }
        let o = d.deserialize_any(Visitor)?;
        let d = Uncertainty::default();
        Ok(Uncertainty {
            method: o.method,
            replicates: o.replicates.unwrap_or(d.replicates),
            seed: o.seed.unwrap_or(d.seed),
        })
    }
}
