//! No NaN, infinity or `null` reaches a report. [`ensure_finite`] walks a report as serde sees
//! it and names the first number that is not finite; [`to_json`] then writes the JSON with
//! absent optional fields left out rather than written as `null` (serde_json would also write
//! NaN as `null`, which is why the check comes first).
use serde::ser::{self, Serialize};
use std::fmt;

/// A report with a figure that is not a finite number.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("the {what} is not finite: `{field}` is {value}")]
pub struct NotFinite {
    /// What the report is of (`fit`, `diagnosis`, `prediction`).
    pub what: &'static str,
    /// The field, as a JSON path (`candidates[1].rss`).
    pub field: String,
    /// `not a number` or `infinite` (the words, so that no `NaN` reaches the terminal either).
    pub value: String,
}

/// Checks every number of `report`; the error names the first that is NaN or infinite.
pub fn ensure_finite<T: Serialize + ?Sized>(what: &'static str, report: &T) -> Result<(), NotFinite> {
    let mut walker = Walker { path: Vec::new() };
    match report.serialize(&mut walker) {
        Ok(()) => Ok(()),
        Err(Found::NotFinite { field, value }) => Err(NotFinite { what, field, value }),
        Err(Found::Other(message)) => Err(NotFinite { what, field: message, value: "unreadable".into() }),
    }
}

/// `report` as pretty JSON, after [`ensure_finite`], with every `null` (an absent optional
/// field) left out.
pub fn to_json<T: Serialize + ?Sized>(what: &'static str, report: &T) -> Result<String, NotFinite> {
    ensure_finite(what, report)?;
    let mut value = serde_json::to_value(report).map_err(|e| NotFinite {
        what,
        field: e.to_string(),
        value: "unreadable".into(),
    })?;
    drop_nulls(&mut value);
    serde_json::to_string_pretty(&value).map_err(|e| NotFinite {
        what,
        field: e.to_string(),
        value: "unreadable".into(),
    })
}

fn drop_nulls(value: &mut serde_json::Value) {
    use serde_json::Value;
    match value {
        Value::Object(fields) => {
            fields.retain(|_, item| !item.is_null());
            fields.values_mut().for_each(drop_nulls);
        }
        Value::Array(items) => items.iter_mut().for_each(drop_nulls),
        _ => {}
    }
}

#[derive(Debug)]
enum Found {
    NotFinite { field: String, value: String },
    Other(String),
}

impl fmt::Display for Found {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Found::NotFinite { field, value } => write!(f, "{field} is {value}"),
            Found::Other(message) => f.write_str(message),
        }
    }
}

impl std::error::Error for Found {}

impl ser::Error for Found {
    fn custom<T: fmt::Display>(message: T) -> Self {
        Found::Other(message.to_string())
    }
}

/// A serializer that writes nothing and stops at the first non-finite float.
struct Walker {
    path: Vec<String>,
}

impl Walker {
    fn float(&self, x: f64) -> Result<(), Found> {
        if x.is_finite() {
            return Ok(());
        }
        let mut field = String::new();
        for part in &self.path {
            if !part.starts_with('[') && !field.is_empty() {
                field.push('.');
            }
            field.push_str(part);
        }
        let value = if x.is_nan() { "not a number" } else { "infinite" };
        Err(Found::NotFinite { field, value: value.to_owned() })
    }

    fn at<T: Serialize + ?Sized>(&mut self, part: String, value: &T) -> Result<(), Found> {
        self.path.push(part);
        let result = value.serialize(&mut *self);
        self.path.pop();
        result
    }
}

type R = Result<(), Found>;

impl<'a> ser::Serializer for &'a mut Walker {
    type Ok = ();
    type Error = Found;
    type SerializeSeq = Seq<'a>;
    type SerializeTuple = Seq<'a>;
    type SerializeTupleStruct = Seq<'a>;
    type SerializeTupleVariant = Seq<'a>;
    type SerializeMap = Seq<'a>;
    type SerializeStruct = Seq<'a>;
    type SerializeStructVariant = Seq<'a>;

    fn serialize_bool(self, _: bool) -> R {
        Ok(())
    }
    fn serialize_i8(self, _: i8) -> R {
        Ok(())
    }
    fn serialize_i16(self, _: i16) -> R {
        Ok(())
    }
    fn serialize_i32(self, _: i32) -> R {
        Ok(())
    }
    fn serialize_u8(self, _: u8) -> R {
        Ok(())
    }
    fn serialize_u16(self, _: u16) -> R {
        Ok(())
    }
    fn serialize_u32(self, _: u32) -> R {
        Ok(())
    }
    fn serialize_i64(self, _: i64) -> R {
        Ok(())
    }
    fn serialize_u64(self, _: u64) -> R {
        Ok(())
    }
    fn serialize_f32(self, x: f32) -> R {
        self.float(f64::from(x))
    }
    fn serialize_f64(self, x: f64) -> R {
        self.float(x)
    }
    fn serialize_char(self, _: char) -> R {
        Ok(())
    }
    fn serialize_str(self, _: &str) -> R {
        Ok(())
    }
    fn serialize_bytes(self, _: &[u8]) -> R {
        Ok(())
    }
    fn serialize_none(self) -> R {
        Ok(())
    }
    fn serialize_some<T: Serialize + ?Sized>(self, value: &T) -> R {
        value.serialize(self)
    }
    fn serialize_unit(self) -> R {
        Ok(())
    }
    fn serialize_unit_struct(self, _: &'static str) -> R {
        Ok(())
    }
    fn serialize_unit_variant(self, _: &'static str, _: u32, _: &'static str) -> R {
        Ok(())
    }
    fn serialize_newtype_struct<T: Serialize + ?Sized>(self, _: &'static str, value: &T) -> R {
        value.serialize(self)
    }
    fn serialize_newtype_variant<T: Serialize + ?Sized>(
        self,
        _: &'static str,
        _: u32,
        variant: &'static str,
        value: &T,
    ) -> R {
        self.at(variant.to_owned(), value)
    }
    fn serialize_seq(self, _: Option<usize>) -> Result<Seq<'a>, Found> {
        Ok(Seq { walker: self, index: 0 })
    }
    fn serialize_tuple(self, _: usize) -> Result<Seq<'a>, Found> {
        Ok(Seq { walker: self, index: 0 })
    }
    fn serialize_tuple_struct(self, _: &'static str, _: usize) -> Result<Seq<'a>, Found> {
        Ok(Seq { walker: self, index: 0 })
    }
    fn serialize_tuple_variant(self, _: &'static str, _: u32, _: &'static str, _: usize) -> Result<Seq<'a>, Found> {
        Ok(Seq { walker: self, index: 0 })
    }
    fn serialize_map(self, _: Option<usize>) -> Result<Seq<'a>, Found> {
        Ok(Seq { walker: self, index: 0 })
    }
    fn serialize_struct(self, _: &'static str, _: usize) -> Result<Seq<'a>, Found> {
        Ok(Seq { walker: self, index: 0 })
    }
    fn serialize_struct_variant(self, _: &'static str, _: u32, _: &'static str, _: usize) -> Result<Seq<'a>, Found> {
        Ok(Seq { walker: self, index: 0 })
    }
}

/// The walker inside a sequence, map or struct: counts elements, names fields.
struct Seq<'a> {
    walker: &'a mut Walker,
    index: usize,
}

impl Seq<'_> {
    fn element<T: Serialize + ?Sized>(&mut self, value: &T) -> R {
        let part = format!("[{}]", self.index);
        self.index += 1;
        self.walker.at(part, value)
    }
}

/// The sequence-like serializer traits: every element is walked in turn.
macro_rules! walk_elements {
    ($($trait:ident :: $method:ident),*) => {$(
        impl ser::$trait for Seq<'_> {
            type Ok = ();
            type Error = Found;
            fn $method<T: Serialize + ?Sized>(&mut self, value: &T) -> R {
                self.element(value)
            }
            fn end(self) -> R {
                Ok(())
            }
        }
    )*};
}

walk_elements!(
    SerializeSeq::serialize_element,
    SerializeTuple::serialize_element,
    SerializeTupleStruct::serialize_field,
    SerializeTupleVariant::serialize_field
);

impl ser::SerializeMap for Seq<'_> {
    type Ok = ();
    type Error = Found;
    fn serialize_key<T: Serialize + ?Sized>(&mut self, key: &T) -> R {
        // A key is named by the value after it; a float key is checked all the same.
        key.serialize(&mut *self.walker)
    }
    fn serialize_value<T: Serialize + ?Sized>(&mut self, value: &T) -> R {
        self.element(value)
    }
    fn end(self) -> R {
        Ok(())
    }
}

impl ser::SerializeStruct for Seq<'_> {
    type Ok = ();
    type Error = Found;
    fn serialize_field<T: Serialize + ?Sized>(&mut self, key: &'static str, value: &T) -> R {
        self.walker.at(key.to_owned(), value)
    }
    fn end(self) -> R {
        Ok(())
    }
}

impl ser::SerializeStructVariant for Seq<'_> {
    type Ok = ();
    type Error = Found;
    fn serialize_field<T: Serialize + ?Sized>(&mut self, key: &'static str, value: &T) -> R {
        self.walker.at(key.to_owned(), value)
    }
    fn end(self) -> R {
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(serde::Serialize)]
    struct Inner {
        rss: f64,
        halves: Option<[f64; 2]>,
    }
    #[derive(serde::Serialize)]
    struct Report {
        n: usize,
        candidates: Vec<Inner>,
    }

    #[test]
    fn names_the_first_field_that_is_not_finite() {
        let good = Report { n: 3, candidates: vec![Inner { rss: 1.0, halves: None }] };
        assert_eq!(ensure_finite("fit", &good), Ok(()));
        let json = to_json("fit", &good).unwrap();
        assert!(!json.contains("null") && !json.contains("halves"), "{json}");
        let bad = Report {
            n: 3,
            candidates: vec![Inner { rss: 1.0, halves: None }, Inner { rss: 2.0, halves: Some([1.0, f64::NAN]) }],
        };
        let err = ensure_finite("fit", &bad).unwrap_err();
        assert_eq!(err.field, "candidates[1].halves[1]");
        assert_eq!(err.to_string(), "the fit is not finite: `candidates[1].halves[1]` is not a number");
        let inf = Report { n: 3, candidates: vec![Inner { rss: f64::INFINITY, halves: None }] };
        assert_eq!(
            to_json("fit", &inf).unwrap_err().to_string(),
            "the fit is not finite: `candidates[0].rss` is infinite"
        );
    }
}
