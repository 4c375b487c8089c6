//! Reading a TOML table's keys through a lookup, so that an unknown key is an
//! error at the key itself: the TOML reader attaches the key's span (its line)
//! to an error raised while the key is read, and only the value's span to one
//! raised later.

use serde::de::{self, DeserializeSeed, Deserializer, Visitor};

/// Reads one key and looks it up; the lookup's `Err` (e.g. "unknown field
/// `x`, expected one of ...") becomes the reader's error at the key.
pub struct KeySeed<F> {
    /// What a key of this table is, for type errors ("a plant parameter").
    pub expecting: &'static str,
    /// The key's meaning, or why it has none.
    pub lookup: F,
}

impl<'de, T, F: FnOnce(&str) -> Result<T, String>> DeserializeSeed<'de> for KeySeed<F> {
    type Value = T;

    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<T, D::Error> {
        d.deserialize_str(self)
    }
}

impl<T, F: FnOnce(&str) -> Result<T, String>> Visitor<'_> for KeySeed<F> {
    type Value = T;

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str(self.expecting)
    }

    fn visit_str<E: de::Error>(self, v: &str) -> Result<T, E> {
        (self.lookup)(v).map_err(E::custom)
    }
}
