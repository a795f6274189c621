//! The command line's flags for the library's choices: their values and help come from each
//! choice's table (`pegtwin::choice::Choice::NAMED`), so every name is spelled once.

use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
use pegtwin::choice::Choice;

/// The parser of a flag that takes one of `T`'s names.
pub fn choice<T: Choice + Clone + Send + Sync>() -> impl TypedValueParser<Value = T> {
    PossibleValuesParser::new(
        T::NAMED
            .iter()
            .map(|n| PossibleValue::new(n.name).help(n.help)),
    )
    .map(|name| T::by_name(&name).expect("clap takes only the listed names"))
}
