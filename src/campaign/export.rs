//! `pegtwin export`: a finished campaign's trial records as one Parquet table, for pandas,
//! polars, DuckDB and Arrow. `trials.jsonl` stays the canonical record; the table is a view of
//! it, one row per trial in the file's order, its columns the ones `pegtwin.load_trials` gives:
//!
//! - `cell`, `trial`, `seed` and every scalar field as it is (units in the field's name);
//! - the hole offset as `offset_x_mm` ... `offset_yaw_deg`, the errors as `error_x_mm` ...
//!   `error_yaw_deg`, the estimate as `estimate_x_m` ... `estimate_yaw_rad` and its standard
//!   deviations as `estimate_std_x_m` ... (null where a trial has none: the direct baseline);
//! - the fault as `fault_reason`, `fault_time_s`, `fault_source`; the phase times as
//!   `time_search_s` ...;
//! - other objects flattened with `_` (`real_cell_contact_friction`, `print_clearance_m`);
//! - arrays as list columns (`insert_fz_n`; `estimate_covariance`, 6 lists of 6).
//!
//! A column's type is read from its values: whole numbers that are never negative become
//! `uint64` (seeds use all 64 bits), other numbers `float64`, then `bool`, `string` and lists of
//! `float64`; a column with no value at all is `float64` when its name carries a unit
//! (`fault_time_s`), else `string`. A field with values of two kinds is refused by name. The
//! columns after the named ones come in the order of the record's field names.

use crate::campaign::run::{TRIALS_FILE, read_finished};
use crate::error::{Error, Result};
use arrow_array::builder::{
    BooleanBuilder, Float64Builder, ListBuilder, StringBuilder, UInt64Builder,
};
use arrow_array::{ArrayRef, RecordBatch};
use arrow_schema::{Field, Schema};
use serde_json::{Map, Value};
use std::collections::HashMap;
use std::io::BufRead;
use std::path::Path;
use std::sync::Arc;

/// The six pose axes as the flat columns name them, with their units.
const POSE_MM_DEG: [&str; 6] = ["x_mm", "y_mm", "z_mm", "roll_deg", "pitch_deg", "yaw_deg"];
const POSE_M_RAD: [&str; 6] = ["x_m", "y_m", "z_m", "roll_rad", "pitch_rad", "yaw_rad"];

/// Writes the trials of the finished campaign folder `dir` to `path` as Parquet (one row per
/// trial; module docs), whole or not at all. Returns the number of rows.
pub fn write_parquet(dir: &Path, path: &Path) -> Result<usize> {
    crate::files::ensure_writable(path)?;
    read_finished(dir)?;
    let trials = dir.join(TRIALS_FILE);
    let table = FlatTable::read(&trials)?;
    let rows = table.rows;
    let batch = table.into_batch(&trials)?;
    let bytes = parquet_bytes(&batch)
        .map_err(|e| Error::file(path, format!("cannot write Parquet: {e}")))?;
    crate::files::write_atomically(path, &bytes)?;
    Ok(rows)
}

/// `batch` as the bytes of a Parquet file (uncompressed).
fn parquet_bytes(batch: &RecordBatch) -> parquet::errors::Result<Vec<u8>> {
    let mut bytes = Vec::new();
    let mut writer = parquet::arrow::ArrowWriter::try_new(&mut bytes, batch.schema(), None)?;
    writer.write(batch)?;
    writer.close()?;
    Ok(bytes)
}

/// The flat rows of a `trials.jsonl`, column by column (absent values are null).
struct FlatTable {
    names: Vec<String>,
    index: HashMap<String, usize>,
    columns: Vec<Vec<Value>>,
    rows: usize,
}

impl FlatTable {
    /// Reads and flattens every record of the file `path`.
    fn read(path: &Path) -> Result<Self> {
        let file = std::fs::File::open(path)
            .map_err(|e| Error::file(path, format!("cannot read: {e}")))?;
        let mut table = FlatTable {
            names: Vec::new(),
            index: HashMap::new(),
            columns: Vec::new(),
            rows: 0,
        };
        for (n, line) in std::io::BufReader::new(file).lines().enumerate() {
            let line = line.map_err(|e| Error::file(path, format!("cannot read: {e}")))?;
            if line.trim().is_empty() {
                continue;
            }
            let bad = |what: String| Error::file(path, format!("line {}: {what}", n + 1));
            let record: Map<String, Value> =
                serde_json::from_str(&line).map_err(|e| bad(format!("not JSON: {e}")))?;
            let row = flat_record(record).map_err(bad)?;
            table.push(row);
        }
        Ok(table)
    }

    /// Appends one flat row: its new columns are null in the rows before.
    fn push(&mut self, row: Vec<(String, Value)>) {
        for (name, value) in row {
            let i = *self.index.entry(name.clone()).or_insert_with(|| {
                self.names.push(name);
                self.columns.push(Vec::new());
                self.columns.len() - 1
            });
            let column = &mut self.columns[i];
            column.resize(self.rows, Value::Null);
            column.push(value);
        }
        self.rows += 1;
        for column in &mut self.columns {
            column.resize(self.rows, Value::Null);
        }
    }

    /// The table as one Arrow record batch (the error names the file and the column).
    fn into_batch(self, path: &Path) -> Result<RecordBatch> {
        let mut fields = Vec::with_capacity(self.names.len());
        let mut arrays = Vec::with_capacity(self.names.len());
        for (name, values) in self.names.iter().zip(&self.columns) {
            let array = column_array(name, values)
                .map_err(|what| Error::file(path, format!("field `{name}`: {what}")))?;
            fields.push(Field::new(name, array.data_type().clone(), true));
            arrays.push(array);
        }
        RecordBatch::try_new(Arc::new(Schema::new(fields)), arrays)
            .map_err(|e| Error::file(path, format!("cannot make the table: {e}")))
    }
}

/// One record as flat (column, value) pairs, as `pegtwin.load_trials` flattens it.
fn flat_record(
    mut record: Map<String, Value>,
) -> std::result::Result<Vec<(String, Value)>, String> {
    let mut row = Vec::new();
    for key in ["cell", "trial"] {
        let v = record
            .remove(key)
            .ok_or(format!("no `{key}`: not a trial record"))?;
        row.push((key.to_owned(), v));
    }
    let offset = record.remove("offset").unwrap_or(Value::Null);
    named_items(&mut row, "offset", &offset, &POSE_MM_DEG);
    let errors = record.remove("errors").unwrap_or(Value::Null);
    for name in POSE_MM_DEG {
        let v = errors.get(name).cloned().unwrap_or(Value::Null);
        row.push((format!("error_{name}"), v));
    }
    let estimate = record.remove("estimate").unwrap_or(Value::Null);
    let std = record.remove("estimate_std").unwrap_or(Value::Null);
    for (i, name) in POSE_M_RAD.iter().enumerate() {
        let item = |v: &Value| v.get(i).cloned().unwrap_or(Value::Null);
        row.push((format!("estimate_{name}"), item(&estimate)));
        row.push((format!("estimate_std_{name}"), item(&std)));
    }
    let fault = record.remove("fault").unwrap_or(Value::Null);
    let field = |v: &Value, key: &str| v.get(key).cloned().unwrap_or(Value::Null);
    row.push(("fault_reason".into(), field(&fault, "reason")));
    row.push(("fault_time_s".into(), field(&fault, "time_s")));
    let energy = field(&fault, "energy");
    row.push(("fault_source".into(), field(&energy, "source")));
    if let Some(Value::Object(times)) = record.remove("times") {
        for (name, v) in times {
            row.push((format!("time_{name}"), v));
        }
    }
    for (key, value) in record {
        flatten_into(&mut row, key, value);
    }
    Ok(row)
}

/// The items of the array `value` as the columns `PREFIX_NAME` (null where it has none).
fn named_items(row: &mut Vec<(String, Value)>, prefix: &str, value: &Value, names: &[&str]) {
    for (i, name) in names.iter().enumerate() {
        let v = value.get(i).cloned().unwrap_or(Value::Null);
        row.push((format!("{prefix}_{name}"), v));
    }
}

/// `value` under the column `name`: an object's fields as `name_field`, recursively.
fn flatten_into(row: &mut Vec<(String, Value)>, name: String, value: Value) {
    match value {
        Value::Object(fields) => {
            for (key, v) in fields {
                flatten_into(row, format!("{name}_{key}"), v);
            }
        }
        v => row.push((name, v)),
    }
}

/// What one column holds, read from its non-null values.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Kind {
    Null,
    UInt,
    Float,
    Bool,
    Text,
    List,
    ListOfLists,
}

/// The kind of one value.
fn kind_of(v: &Value) -> std::result::Result<Kind, String> {
    Ok(match v {
        Value::Null => Kind::Null,
        Value::Bool(_) => Kind::Bool,
        Value::String(_) => Kind::Text,
        Value::Number(n) if n.is_u64() => Kind::UInt,
        Value::Number(_) => Kind::Float,
        Value::Array(items) => match items.first() {
            Some(Value::Array(_)) => Kind::ListOfLists,
            _ => Kind::List,
        },
        Value::Object(_) => return Err("an object inside an array: expected numbers".into()),
    })
}

/// The kind of a whole column: numbers that are whole in some rows and not in others are
/// floats; any other mix is refused.
fn column_kind(values: &[Value]) -> std::result::Result<Kind, String> {
    let mut kind = Kind::Null;
    for v in values {
        let k = kind_of(v)?;
        kind = match (kind, k) {
            (a, Kind::Null) => a,
            (Kind::Null, b) => b,
            (a, b) if a == b => a,
            (Kind::UInt | Kind::Float, Kind::UInt | Kind::Float) => Kind::Float,
            (Kind::List | Kind::ListOfLists, Kind::List | Kind::ListOfLists)
                if v.as_array().is_some_and(|a| a.is_empty()) =>
            {
                kind
            }
            (a, b) => return Err(format!("holds values of two kinds ({a:?} and {b:?})")),
        };
    }
    Ok(kind)
}

/// Whether the column `name` carries a unit, so holds numbers even where every value is null
/// (`fault_time_s` of a campaign without faults).
fn has_unit(name: &str) -> bool {
    const UNITS: [&str; 6] = ["_s", "_m", "_mm", "_deg", "_rad", "_n"];
    UNITS.iter().any(|u| name.ends_with(u))
}

/// The column `name` as an Arrow array of its values' kind.
fn column_array(name: &str, values: &[Value]) -> std::result::Result<ArrayRef, String> {
    Ok(match column_kind(values)? {
        Kind::UInt => {
            let mut b = UInt64Builder::with_capacity(values.len());
            values.iter().for_each(|v| b.append_option(v.as_u64()));
            Arc::new(b.finish())
        }
        Kind::Float => {
            let mut b = Float64Builder::with_capacity(values.len());
            values.iter().for_each(|v| b.append_option(v.as_f64()));
            Arc::new(b.finish())
        }
        Kind::Bool => {
            let mut b = BooleanBuilder::with_capacity(values.len());
            values.iter().for_each(|v| b.append_option(v.as_bool()));
            Arc::new(b.finish())
        }
        Kind::Null if has_unit(name) => {
            let mut b = Float64Builder::with_capacity(values.len());
            b.append_nulls(values.len());
            Arc::new(b.finish())
        }
        Kind::Null | Kind::Text => {
            let mut b = StringBuilder::new();
            values.iter().for_each(|v| b.append_option(v.as_str()));
            Arc::new(b.finish())
        }
        Kind::List => {
            let mut b = ListBuilder::new(Float64Builder::new());
            for v in values {
                append_floats(&mut b, v)?;
            }
            Arc::new(b.finish())
        }
        Kind::ListOfLists => {
            let mut b = ListBuilder::new(ListBuilder::new(Float64Builder::new()));
            for v in values {
                match v.as_array() {
                    None => b.append_null(),
                    Some(rows) => {
                        for row in rows {
                            append_floats(b.values(), row)?;
                        }
                        b.append(true);
                    }
                }
            }
            Arc::new(b.finish())
        }
    })
}

/// Appends the array of numbers `v` (or null) as one list.
fn append_floats(
    b: &mut ListBuilder<Float64Builder>,
    v: &Value,
) -> std::result::Result<(), String> {
    let Some(items) = v.as_array() else {
        b.append_null();
        return Ok(());
    };
    for item in items {
        let x = item
            .as_f64()
            .ok_or_else(|| format!("{item} in a list: expected numbers"))?;
        b.values().append_value(x);
    }
    b.append(true);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_record_flattens_as_load_trials_does() {
        let record = serde_json::json!({
            "cell": 1, "trial": 2, "seed": u64::MAX, "outcome": "success",
            "offset": [1.0, 2.0, 3.0, 4.0, 5.0, 6.0],
            "errors": null, "estimate": null, "fault": {"reason": "r", "time_s": 0.5},
            "times": {"search_s": 0.0}, "print": {"clearance_m": 4e-4},
            "insert_fz_n": [1.0, 2.5],
        });
        let Value::Object(record) = record else {
            unreachable!()
        };
        let row: HashMap<String, Value> = flat_record(record).unwrap().into_iter().collect();
        assert_eq!(row["seed"], serde_json::json!(u64::MAX));
        assert_eq!(row["offset_yaw_deg"], serde_json::json!(6.0));
        assert_eq!(row["error_x_mm"], Value::Null);
        assert_eq!(row["estimate_std_yaw_rad"], Value::Null);
        assert_eq!(row["fault_reason"], serde_json::json!("r"));
        assert_eq!(row["fault_source"], Value::Null);
        assert_eq!(row["time_search_s"], serde_json::json!(0.0));
        assert_eq!(row["print_clearance_m"], serde_json::json!(4e-4));
        assert_eq!(row["insert_fz_n"], serde_json::json!([1.0, 2.5]));
    }

    #[test]
    fn a_column_of_two_kinds_is_refused_by_name() {
        let values = [serde_json::json!(1.5), serde_json::json!("x")];
        let e = column_array("x", &values).unwrap_err();
        assert!(e.contains("two kinds"), "{e}");
        let mixed = [serde_json::json!(1), serde_json::json!(1.5), Value::Null];
        assert_eq!(column_kind(&mixed).unwrap(), Kind::Float);
        let nulls = [Value::Null, Value::Null];
        let times = column_array("fault_time_s", &nulls).unwrap();
        assert_eq!(times.data_type(), &arrow_schema::DataType::Float64);
        let reasons = column_array("fault_reason", &nulls).unwrap();
        assert_eq!(reasons.data_type(), &arrow_schema::DataType::Utf8);
    }
}
