//! One list of names per enum: [`names!`] gives an enum of unit variants its `as_str`, `ALL`,
//! `from_name` and serde's `Serialize`/`Deserialize` from the same `Variant = "name"` pairs, so
//! the name written to a file, read back and printed cannot drift apart. Deserialising an
//! unknown name fails with serde's own message ("unknown variant `x`, expected one of ...").

/// `names!(Type { A = "a", B = "b" })` after `enum Type { A, B }` (unit variants, each listed
/// once: the match in `as_str` fails to compile when one is missing).
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

            /// The variant called `name`.
            pub fn from_name(name: &str) -> Option<$ty> {
                match name {
                    $($name => Some($ty::$variant),)+
                    _ => None,
                }
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
                        write!(f, "one of {:?}", $ty::NAMES)
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

#[cfg(test)]
mod tests {
    use crate::data::Offset;
    use crate::estimate::{InitialState, Termination};
    use crate::export::continuous::Method;
    use crate::job::StartStrategy;
    use crate::reduce::Rule;
    use crate::spectral::SpectrumMethod;
    use crate::table::{FitKind, Status};

    /// Every name of `T` through serde and back: the JSON string is `as_str`, and it reads back
    /// as the same variant; an unknown name gets serde's message listing them.
    fn roundtrip<T>(all: &[T], as_str: fn(&T) -> &'static str)
    where
        T: serde::Serialize + serde::de::DeserializeOwned + PartialEq + std::fmt::Debug,
    {
        for v in all {
            assert_eq!(serde_json::to_string(v).unwrap(), format!("\"{}\"", as_str(v)));
            assert_eq!(&serde_json::from_str::<T>(&format!("\"{}\"", as_str(v))).unwrap(), v);
        }
        let e = serde_json::from_str::<T>("\"no-such-name\"").unwrap_err().to_string();
        assert!(e.contains("unknown variant `no-such-name`, expected") && e.contains(as_str(&all[0])), "{e}");
    }

    /// The command line's names (clap's `ValueEnum`) are the files' names too.
    fn same_on_the_command_line<T: clap::ValueEnum>(as_str: fn(&T) -> &'static str) {
        for v in T::value_variants() {
            assert_eq!(v.to_possible_value().unwrap().get_name(), as_str(v));
        }
    }

    #[test]
    fn serde_and_the_command_line_use_the_one_list_of_names() {
        roundtrip(Offset::ALL, |v| v.as_str());
        roundtrip(InitialState::ALL, |v| v.as_str());
        roundtrip(Termination::ALL, |v| v.as_str());
        roundtrip(Method::ALL, |v| v.as_str());
        roundtrip(StartStrategy::ALL, |v| v.as_str());
        roundtrip(Rule::ALL, |v| v.as_str());
        roundtrip(SpectrumMethod::ALL, |v| v.as_str());
        roundtrip(FitKind::ALL, |v| v.as_str());
        roundtrip(Status::ALL, |v| v.as_str());
        same_on_the_command_line::<Offset>(|v| v.as_str());
        same_on_the_command_line::<InitialState>(|v| v.as_str());
        same_on_the_command_line::<SpectrumMethod>(|v| v.as_str());
    }
}
