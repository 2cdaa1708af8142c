//! An option's value as a front door hands it over: text from a command line, a TOML file, an
//! IPP attribute or a `key=value` string, or a typed value from Python, JavaScript or TOML.
//! Each option's parser in [`super::table`] takes either form.

use std::borrow::Cow;
use std::fmt;

/// One option value, typed or as text.
#[derive(Clone, Debug, PartialEq)]
pub enum Value<'a> {
    /// True or false (`--invert`, `invert=True`).
    Bool(bool),
    /// A whole number.
    Int(i64),
    /// A number.
    Float(f64),
    /// Text, parsed by the option (`"50%"`, `"800x480"`, `"auto"`, a name or a path).
    Text(Cow<'a, str>),
    /// Two whole numbers (`fit=(800, 480)` from Python).
    Pair(u64, u64),
}

impl fmt::Display for Value<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Value::Bool(b) => write!(f, "{b}"),
            Value::Int(i) => write!(f, "{i}"),
            Value::Float(x) => write!(f, "{x}"),
            Value::Text(t) => f.write_str(t),
            Value::Pair(a, b) => write!(f, "{a}x{b}"),
        }
    }
}

impl<'a> From<&'a str> for Value<'a> {
    fn from(s: &'a str) -> Self {
        Value::Text(Cow::Borrowed(s))
    }
}

impl From<String> for Value<'static> {
    fn from(s: String) -> Self {
        Value::Text(Cow::Owned(s))
    }
}

impl From<bool> for Value<'static> {
    fn from(b: bool) -> Self {
        Value::Bool(b)
    }
}

impl From<i64> for Value<'static> {
    fn from(i: i64) -> Self {
        Value::Int(i)
    }
}

impl From<f64> for Value<'static> {
    fn from(x: f64) -> Self {
        Value::Float(x)
    }
}

impl Value<'_> {
    /// The value as text (numbers as Rust writes them, pairs as `WxH`).
    pub fn text(&self) -> Cow<'_, str> {
        match self {
            Value::Text(t) => Cow::Borrowed(t.as_ref()),
            other => Cow::Owned(other.to_string()),
        }
    }

    /// An owned copy.
    pub fn into_owned(self) -> Value<'static> {
        match self {
            Value::Text(t) => Value::Text(Cow::Owned(t.into_owned())),
            Value::Bool(b) => Value::Bool(b),
            Value::Int(i) => Value::Int(i),
            Value::Float(x) => Value::Float(x),
            Value::Pair(a, b) => Value::Pair(a, b),
        }
    }

    /// The value of a TOML entry (presets, queue files); arrays and tables are refused by
    /// the options that do not take them.
    pub fn from_toml(v: &toml::Value) -> Value<'static> {
        match v {
            toml::Value::Boolean(b) => Value::Bool(*b),
            toml::Value::Integer(i) => Value::Int(*i),
            toml::Value::Float(x) => Value::Float(*x),
            toml::Value::String(s) => Value::Text(Cow::Owned(s.clone())),
            other => Value::Text(Cow::Owned(other.to_string())),
        }
    }

    /// The value of a JSON entry (the browser page).
    pub fn from_json(v: &serde_json::Value) -> Value<'static> {
        match v {
            serde_json::Value::Bool(b) => Value::Bool(*b),
            serde_json::Value::Number(n) => match n.as_i64() {
                Some(i) => Value::Int(i),
                None => Value::Float(n.as_f64().unwrap_or(f64::NAN)),
            },
            serde_json::Value::String(s) => Value::Text(Cow::Owned(s.clone())),
            other => Value::Text(Cow::Owned(other.to_string())),
        }
    }

    /// True or false: a boolean, or the words true/false, yes/no, on/off, 1/0.
    pub(super) fn boolean(&self) -> std::result::Result<bool, String> {
        match self {
            Value::Bool(b) => Ok(*b),
            Value::Int(0) => Ok(false),
            Value::Int(1) => Ok(true),
            Value::Text(t) => match t.trim().to_ascii_lowercase().as_str() {
                "true" | "yes" | "on" | "1" => Ok(true),
                "false" | "no" | "off" | "0" => Ok(false),
                _ => Err(format!("'{t}': expected true or false")),
            },
            other => Err(format!("'{other}': expected true or false")),
        }
    }

    /// A whole number in `lo..=hi`; `what` completes "expected …" in the message.
    pub(super) fn whole(&self, lo: i128, hi: i128) -> std::result::Result<i128, String> {
        let range = || format!("must be a whole number from {lo} to {hi}");
        let n: i128 = match self {
            Value::Int(i) => *i as i128,
            Value::Float(x) if x.fract() == 0.0 && x.is_finite() => *x as i128,
            Value::Text(t) => match t.trim().parse::<i128>() {
                Ok(n) => n,
                Err(e) => {
                    use std::num::IntErrorKind::{NegOverflow, PosOverflow};
                    return Err(match e.kind() {
                        PosOverflow => format!("too large: {}", range()),
                        NegOverflow => range(),
                        _ => format!("'{t}': expected a whole number"),
                    });
                }
            },
            other => return Err(format!("'{other}': expected a whole number")),
        };
        if n > hi {
            return Err(format!("too large: {}", range()));
        }
        if n < lo {
            return Err(range());
        }
        Ok(n)
    }

    /// Any number, infinities and NaN included (callers that need a range check it).
    pub(super) fn any_number(&self) -> std::result::Result<f64, String> {
        match self {
            Value::Int(i) => Ok(*i as f64),
            Value::Float(x) => Ok(*x),
            Value::Text(t) => t
                .trim()
                .parse::<f64>()
                .map_err(|_| format!("'{t}': expected a number")),
            other => Err(format!("'{other}': expected a number")),
        }
    }

    /// A finite number.
    pub(super) fn number(&self) -> std::result::Result<f64, String> {
        let x = self.any_number()?;
        if !x.is_finite() {
            return Err(format!("'{self}': expected a finite number"));
        }
        Ok(x)
    }
}
