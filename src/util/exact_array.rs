//! Fixed-size arrays in configuration files that must have exactly their length.
//!
//! serde's `[T; N]` reads the first N elements of a sequence and leaves the rest unread, and the `toml` crate does
//! not object to what is left, so `resolution = [64, 64, "junk"]` would be accepted as `[64, 64]`. These
//! `deserialize_with` functions read the whole sequence (so a wrong type anywhere is the deserializer's usual error,
//! with its line and key) and then require exactly N elements.

use serde::de::{Deserialize, Deserializer, Error};

/// `#[serde(deserialize_with = "crate::util::exact_array::array")]`: exactly `N` elements.
pub fn array<'de, D, T, const N: usize>(deserializer: D) -> Result<[T; N], D::Error>
where
    D: Deserializer<'de>,
    T: Deserialize<'de>,
{
    let values = Vec::<T>::deserialize(deserializer)?;
    let len = values.len();
    values
        .try_into()
        .map_err(|_| D::Error::invalid_length(len, &format!("an array of {N} values").as_str()))
}

/// As [`array()`], for an optional key (use with `#[serde(default)]`).
pub fn option_array<'de, D, T, const N: usize>(deserializer: D) -> Result<Option<[T; N]>, D::Error>
where
    D: Deserializer<'de>,
    T: Deserialize<'de>,
{
    array(deserializer).map(Some)
}

#[cfg(test)]
mod tests {
    #[derive(Debug, serde::Deserialize)]
    struct T {
        #[serde(deserialize_with = "super::array")]
        v: [u32; 2],
        #[serde(default, deserialize_with = "super::option_array")]
        o: Option<[f32; 3]>,
    }

    #[test]
    fn only_exactly_n_elements_of_the_right_type_are_accepted() {
        let t: T = toml::from_str("v = [1, 2]\no = [1.0, 2.0, 3.0]").unwrap();
        assert_eq!((t.v, t.o), ([1, 2], Some([1.0, 2.0, 3.0])));
        assert_eq!(toml::from_str::<T>("v = [1, 2]").unwrap().o, None);
        for (text, want) in [
            ("v = [64, 64, \"junk\"]", "invalid type"),
            (
                "v = [64, 64, 64]",
                "invalid length 3, expected an array of 2 values",
            ),
            ("v = [64]", "invalid length 1"),
            ("v = [1, 2]\no = [1.0, 2.0, 3.0, 4.0]", "invalid length 4"),
        ] {
            let e = toml::from_str::<T>(text).unwrap_err().to_string();
            assert!(e.contains(want), "{text}: {e}");
        }
    }
}
