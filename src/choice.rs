//! A choice among named values, spelled once. The names a record, a scenario file, a flag and the
//! Python package use for a method, a start, a solver, a replay policy, a tuning target or a
//! mesh unit all come from its [`Choice::NAMED`] table; the command line builds its flags' values
//! and their help from it, and the serde names are tested against it.

use crate::error::{Error, Result};

/// One value of a choice: its name and a line of help.
pub struct Named<T: 'static> {
    pub name: &'static str,
    pub value: T,
    pub help: &'static str,
}

/// A closed set of values, each with one name.
pub trait Choice: Copy + PartialEq + Sized + 'static {
    /// What is chosen, in words (`method`).
    const WHAT: &'static str;
    /// Every value, its name and its help.
    const NAMED: &'static [Named<Self>];

    /// The value's name.
    fn name(self) -> &'static str {
        Self::NAMED
            .iter()
            .find(|n| n.value == self)
            .expect("every value is named")
            .name
    }

    /// The value of `name`; an error naming the choice and every name otherwise.
    fn by_name(name: &str) -> Result<Self> {
        Self::NAMED
            .iter()
            .find(|n| n.name == name)
            .map(|n| n.value)
            .ok_or_else(|| {
                let names: Vec<&str> = Self::NAMED.iter().map(|n| n.name).collect();
                Error::Input(format!(
                    "{} '{name}': expected {}",
                    Self::WHAT,
                    one_of(&names)
                ))
            })
    }
}

/// `a`, `a or b`, `a, b or c`.
fn one_of(names: &[&str]) -> String {
    match names {
        [] => String::new(),
        [one] => one.to_string(),
        [rest @ .., last] => format!("{} or {last}", rest.join(", ")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::Serialize;

    /// The serde name of every value of `T` is its `Choice` name.
    fn serde_names_agree<T: Choice + Serialize>() {
        for n in T::NAMED {
            assert_eq!(
                serde_json::to_value(n.value).unwrap(),
                serde_json::Value::String(n.name.into()),
                "{}",
                T::WHAT
            );
            assert!(T::by_name(n.name).unwrap() == n.value);
            assert_eq!(n.value.name(), n.name);
        }
    }

    #[test]
    fn every_choice_is_named_as_serde_names_it() {
        use crate::campaign::replays::Replays;
        use crate::method::config::{Method, Start};
        use crate::method::register::Solver;
        use crate::twin::geometry::mesh::MeshUnits;
        serde_names_agree::<Method>();
        serde_names_agree::<Start>();
        serde_names_agree::<Solver>();
        serde_names_agree::<Replays>();
        serde_names_agree::<MeshUnits>();
        serde_names_agree::<crate::method::manifold::cache::Sampler>();
        serde_names_agree::<crate::method::adaptive::ObservationStop>();
    }

    #[test]
    fn an_unknown_name_is_refused_with_every_name() {
        #[derive(Clone, Copy, PartialEq, Serialize)]
        #[serde(rename_all = "lowercase")]
        enum Colour {
            Red,
            Green,
            Blue,
        }
        impl Choice for Colour {
            const WHAT: &'static str = "colour";
            const NAMED: &'static [Named<Self>] = &[
                Named {
                    name: "red",
                    value: Colour::Red,
                    help: "",
                },
                Named {
                    name: "green",
                    value: Colour::Green,
                    help: "",
                },
                Named {
                    name: "blue",
                    value: Colour::Blue,
                    help: "",
                },
            ];
        }
        serde_names_agree::<Colour>();
        let e = Colour::by_name("pink").err().unwrap().to_string();
        assert_eq!(e, "colour 'pink': expected red, green or blue");
    }
}
