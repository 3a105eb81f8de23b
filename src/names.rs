//! One list of names per enum: [`names!`] gives an enum of unit variants its `as_str`, `ALL`,
//! `from_name`, serde's `Serialize`/`Deserialize` and clap's `ValueEnum` from the same
//! `Variant = "name"` pairs, so the name written to a file, read back, typed on the command line
//! and printed cannot drift apart.
//!
//! One spelling is written and documented: the listed one, words joined by `_` (`gauss_newton`,
//! `paper_m1`, as job files always had them). The other, with `-` (`gauss-newton`, as command
//! lines are often typed), is read as the same name in a job file, a results file and on the
//! command line, so neither place refuses what the other shows. Reading an unknown name fails
//! with serde's own message listing the written names ("unknown variant `x`, expected one of
//! ...").

/// True when `given` is `name` in either spelling: `-` and `_` count as the same letter.
pub(crate) fn same_name(name: &str, given: &str) -> bool {
    let norm = |b: u8| if b == b'-' { b'_' } else { b };
    name.len() == given.len() && name.bytes().zip(given.bytes()).all(|(a, b)| norm(a) == norm(b))
}

/// `name` with `_` and `-` swapped: its other spelling, as a byte array of the name's length
/// (for [`names!`], which makes a `&'static str` of it at compile time for clap's alias).
pub(crate) const fn other_spelling<const N: usize>(name: &str) -> [u8; N] {
    let bytes = name.as_bytes();
    let mut out = [0u8; N];
    let mut i = 0;
    while i < N {
        out[i] = match bytes[i] {
            b'_' => b'-',
            b'-' => b'_',
            b => b,
        };
        i += 1;
    }
    out
}

/// `names!(Type { A = "a", B = "b" })` after `enum Type { A, B }` (unit variants, each listed
/// once: the match in `as_str` fails to compile when one is missing). The enum derives neither
/// serde's traits nor clap's `ValueEnum`: this gives them.
macro_rules! names {
    ($ty:ident { $($variant:ident = $name:literal),+ $(,)? }) => {
        impl $ty {
            /// Every variant, in declaration order.
            pub const ALL: &'static [$ty] = &[$($ty::$variant),+];
            /// The names, in the order of [`Self::ALL`].
            pub const NAMES: &'static [&'static str] = &[$($name),+];

            /// The name in files, tables and messages.
            pub fn as_str(self) -> &'static str {
                match self {
                    $($ty::$variant => $name),+
                }
            }

            /// The variant called `name`, in either spelling (`_` or `-`, module docs).
            pub fn from_name(name: &str) -> Option<$ty> {
                $ty::NAMES.iter().position(|n| $crate::names::same_name(n, name)).map(|i| $ty::ALL[i])
            }
        }

        impl clap::ValueEnum for $ty {
            fn value_variants<'a>() -> &'a [Self] {
                $ty::ALL
            }

            /// The written name, with the other spelling as a hidden alias.
            fn to_possible_value(&self) -> Option<clap::builder::PossibleValue> {
                let (name, other): (&'static str, &'static str) = match self {
                    $($ty::$variant => {
                        const OTHER: [u8; $name.len()] = $crate::names::other_spelling($name);
                        const TEXT: &str = match std::str::from_utf8(&OTHER) {
                            Ok(s) => s,
                            Err(_) => panic!("a name is ASCII"),
                        };
                        ($name, TEXT)
                    }),+
                };
                let value = clap::builder::PossibleValue::new(name);
                Some(if other == name { value } else { value.alias(other) })
            }
        }

        impl serde::Serialize for $ty {
            fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
                s.serialize_str(self.as_str())
            }
        }

        impl<'de> serde::Deserialize<'de> for $ty {
            fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
                struct Visitor;
                impl serde::de::Visitor<'_> for Visitor {
                    type Value = $ty;
                    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                        write!(f, "one of {}", $crate::names::quoted($ty::NAMES))
                    }
                    fn visit_str<E: serde::de::Error>(self, v: &str) -> std::result::Result<$ty, E> {
                        $ty::from_name(v).ok_or_else(|| E::unknown_variant(v, $ty::NAMES))
                    }
                }
                d.deserialize_str(Visitor)
            }
        }
    };
}
pub(crate) use names;

/// `"a", "b", "c"`: the names as a message lists them.
pub(crate) fn quoted(names: &[&str]) -> String {
    names.iter().map(|n| format!("\"{n}\"")).collect::<Vec<_>>().join(", ")
}

#[cfg(test)]
mod tests {
    use super::{other_spelling, same_name};
    use crate::cli::ExportFormat;
    use crate::data::Offset;
    use crate::estimate::{HuberHessian, InitialState, SolverMethod, Termination};
    use crate::export::continuous::Method;
    use crate::job::{SearchMode, Spacing, StartStrategy, UncertaintyMethod};
    use crate::reduce::{FitBasis, Rule};
    use crate::spectral::SpectrumMethod;
    use crate::table::{FitKind, Status};
    use std::collections::BTreeSet;

    /// Every name of `T` through serde and clap, in both spellings: serde writes the listed name
    /// and reads either back as the same variant, clap's parser (as the command line's
    /// `value_enum` arguments use it) takes either and shows the listed one; an unknown name gets
    /// serde's message listing them. Returns the type's name, for [`every_enum_is_checked`].
    fn check<T>() -> &'static str
    where
        T: clap::ValueEnum + serde::Serialize + serde::de::DeserializeOwned + PartialEq + std::fmt::Debug + Send + Sync,
        T: Clone + 'static,
    {
        let cmd = clap::Command::new("t")
            .arg(clap::Arg::new("v").long("v").value_parser(clap::builder::EnumValueParser::<T>::new()));
        for v in T::value_variants() {
            let name = serde_json::to_value(v).unwrap().as_str().unwrap().to_string();
            let shown = v.to_possible_value().unwrap();
            assert_eq!(shown.get_name(), name, "{v:?}: clap shows another name than files hold");
            assert!(!name.contains('-'), "{name}: the written spelling joins words with '_'");
            for given in [name.clone(), name.replace('_', "-")] {
                let read: T = serde_json::from_value(serde_json::Value::String(given.clone()))
                    .unwrap_or_else(|e| panic!("{}: '{given}' in a file: {e}", std::any::type_name::<T>()));
                assert_eq!(&read, v, "'{given}' in a file");
                let m = cmd.clone().try_get_matches_from(["t", "--v", &given]);
                let m =
                    m.unwrap_or_else(|e| panic!("{}: '{given}' on the command line: {e}", std::any::type_name::<T>()));
                assert_eq!(m.get_one::<T>("v"), Some(v), "'{given}' on the command line");
            }
        }
        let e = serde_json::from_str::<T>("\"no-such-name\"").unwrap_err().to_string();
        let first = serde_json::to_value(&T::value_variants()[0]).unwrap();
        assert!(e.contains("unknown variant `no-such-name`, expected") && e.contains(first.as_str().unwrap()), "{e}");
        std::any::type_name::<T>().rsplit("::").next().unwrap()
    }

    #[test]
    fn either_spelling_is_the_same_name() {
        assert!(same_name("gauss_newton", "gauss-newton") && same_name("gauss_newton", "gauss_newton"));
        assert!(!same_name("gauss_newton", "gaussnewton") && !same_name("ls", "lm"));
        assert_eq!(&other_spelling::<8>("paper_m1"), b"paper-m1");
    }

    /// Every enum made by `names!` in the sources is checked by [`check`], so a new one cannot be
    /// left out; and no enum takes its names from serde's or clap's derive (`rename_all`,
    /// `derive(ValueEnum)`), which would give a file and the command line their own spellings.
    #[test]
    fn every_enum_is_checked_in_both_spellings() {
        let checked: BTreeSet<&str> = [
            check::<ExportFormat>(),
            check::<FitBasis>(),
            check::<FitKind>(),
            check::<HuberHessian>(),
            check::<InitialState>(),
            check::<Method>(),
            check::<Offset>(),
            check::<Rule>(),
            check::<SearchMode>(),
            check::<SolverMethod>(),
            check::<Spacing>(),
            check::<SpectrumMethod>(),
            check::<StartStrategy>(),
            check::<Status>(),
            check::<Termination>(),
            check::<UncertaintyMethod>(),
        ]
        .into_iter()
        .collect();
        let mut files = Vec::new();
        sources(&std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("src"), &mut files);
        let mut made = BTreeSet::new();
        for file in &files {
            let text = std::fs::read_to_string(file).unwrap();
            for (i, _) in text.match_indices("names!(") {
                let ty: String = text[i + 7..].chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect();
                if !ty.is_empty() {
                    made.insert(ty);
                }
            }
            let code = text.split("#[cfg(test)]").next().unwrap();
            for banned in ["ValueEnum)", "ValueEnum,", "rename_all"] {
                assert!(!code.contains(banned), "{}: an enum's names come from names! ({banned})", file.display());
            }
        }
        let made: BTreeSet<&str> = made.iter().map(String::as_str).collect();
        assert_eq!(made, checked, "the enums of names! in src/ and the ones this test checks");
    }

    fn sources(dir: &std::path::Path, out: &mut Vec<std::path::PathBuf>) {
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                sources(&path, out);
            } else if path.extension().is_some_and(|e| e == "rs") && !path.ends_with("names.rs") {
                out.push(path);
            }
        }
    }
}
