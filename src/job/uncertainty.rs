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

#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq, Eq, Default)]
#[serde(rename_all = "snake_case")]
pub enum UncertaintyMethod {
    /// The sandwich covariance at the fit only.
    #[default]
    Local,
    /// The bootstrap of the whole estimation of the watched picks besides.
    Bootstrap,
}

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

impl<'de> Deserialize<'de> for Uncertainty {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        use serde::de::Error as _;
        let v = serde_json::Value::deserialize(d)?;
        let o = match v {
            v @ serde_json::Value::String(_) => {
                let method =
                    UncertaintyMethod::deserialize(v).map_err(|e| D::Error::custom(format!("uncertainty: {e}")))?;
                UncertaintyObject { method, replicates: None, seed: None }
            }
            v @ serde_json::Value::Object(_) => {
                UncertaintyObject::deserialize(v).map_err(|e| D::Error::custom(format!("uncertainty: {e}")))?
            }
            other => {
                return Err(D::Error::custom(format!(
                    "uncertainty: expected \"local\", \"bootstrap\" or {{\"method\": \"bootstrap\", \"replicates\": B, \"seed\": S}}, got {other}"
                )));
            }
        };
        if o.method == UncertaintyMethod::Local && (o.replicates.is_some() || o.seed.is_some()) {
            return Err(D::Error::custom(
                "uncertainty: 'replicates' and 'seed' are settings of the method \"bootstrap\"",
            ));
        }
        let d = Uncertainty::default();
        Ok(Uncertainty {
            method: o.method,
            replicates: o.replicates.unwrap_or(d.replicates),
            seed: o.seed.unwrap_or(d.seed),
        })
    }
}
