//! The command line's arguments, parsed with clap and turned into the
//! library's settings: the library itself knows nothing of clap.

pub mod experiment;
pub mod synth;
pub mod view;

use std::str::FromStr;

use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
use strum::{EnumMessage, VariantArray};

/// The parser of one of the library's closed sets: each value's name and
/// doc line listed in `--help`, the text parsed by the enum's own
/// `FromStr`, so that the names are written once, on the enum.
pub fn choice<T>() -> impl TypedValueParser<Value = T>
where
    T: VariantArray + EnumMessage + FromStr + Into<&'static str> + Copy + Send + Sync,
    T: 'static,
{
    let values = T::VARIANTS.iter().map(|&v| {
        let value = PossibleValue::new(v.into());
        match v.get_documentation() {
            // A doc comment's lines are one paragraph of help.
            Some(doc) => value.help(doc.split_whitespace().collect::<Vec<_>>().join(" ")),
            None => value,
        }
    });
    PossibleValuesParser::new(values).map(|name| match name.parse::<T>() {
        Ok(v) => v,
        Err(_) => unreachable!("`{name}` is one of the names the enum lists"),
    })
}
