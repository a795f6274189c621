//! TOML as a user writes it, read strictly: unknown fields are refused by each type
//! (`deny_unknown_fields`), and an array longer than the field it fills is refused here (serde
//! reads the first N elements of a fixed-size array and drops the rest: `frame_xyz_mm =
//! [0, 0, 0, 1e308]` once read as the origin). Every file type that is TOML reads through
//! [`parse`].

use serde::Serialize;
use serde::de::DeserializeOwned;

/// `text` read as a `T`, or a message naming the line or the field.
pub fn parse<T: DeserializeOwned + Serialize>(text: &str) -> Result<T, String> {
    let value: T = toml::from_str(text).map_err(|e| {
        let line = e
            .span()
            .map(|s| format!("line {}: ", text[..s.start].matches('\n').count() + 1))
            .unwrap_or_default();
        format!("{line}{}", e.message())
    })?;
    let given: toml::Value = toml::from_str(text).map_err(|e| e.message().to_string())?;
    let read = toml::Value::try_from(&value).map_err(|e| e.to_string())?;
    no_dropped_elements(&given, &read, "")?;
    Ok(value)
}

/// Refuses an array of `given` longer than the same field as it was read (`read`): elements the
/// reader dropped. Fields the reader writes back in another shape, or not at all, are left to
/// their own type's checks.
fn no_dropped_elements(given: &toml::Value, read: &toml::Value, at: &str) -> Result<(), String> {
    match (given, read) {
        (toml::Value::Table(g), toml::Value::Table(r)) => {
            for (key, value) in g {
                if let Some(read) = r.get(key) {
                    let field = if at.is_empty() {
                        key.clone()
                    } else {
                        format!("{at}.{key}")
                    };
                    no_dropped_elements(value, read, &field)?;
                }
            }
            Ok(())
        }
        (toml::Value::Array(g), toml::Value::Array(r)) => {
            if g.len() > r.len() {
                return Err(format!(
                    "{at}: {} values given, expected {}",
                    g.len(),
                    r.len()
                ));
            }
            for (k, (g, r)) in g.iter().zip(r).enumerate() {
                no_dropped_elements(g, r, &format!("{at}[{k}]"))?;
            }
            Ok(())
        }
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, serde::Deserialize, serde::Serialize)]
    #[serde(deny_unknown_fields)]
    struct Frame {
        xyz: [f64; 3],
        names: Vec<String>,
        inner: Option<Inner>,
    }

    #[derive(Debug, serde::Deserialize, serde::Serialize)]
    struct Inner {
        rpy: [f64; 3],
    }

    #[test]
    fn an_array_longer_than_its_field_is_refused_by_name() {
        let ok: Frame = parse("xyz = [1, 2, 3]\nnames = [\"a\", \"b\"]\n").unwrap();
        assert_eq!(ok.names.len(), 2);
        let err = parse::<Frame>("xyz = [1, 2, 3, 1e308]\nnames = []\n").unwrap_err();
        assert_eq!(err, "xyz: 4 values given, expected 3");
        let err = parse::<Frame>("xyz = [1, 2, 3]\nnames = []\n[inner]\nrpy = [0, 0, 0, 0]\n")
            .unwrap_err();
        assert_eq!(err, "inner.rpy: 4 values given, expected 3");
        assert!(
            parse::<Frame>("xyz = [1, 2]\nnames = []\n")
                .unwrap_err()
                .contains("line 1")
        );
    }
}
