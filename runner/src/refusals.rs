//! Refusals of a plan, each naming its field and the rule it breaks, gathered so that one
//! request answers every mistake at once; and a JSON table read field by field, each
//! field's type and range checked, unknown fields named with the nearest known one.

use serde::Serialize;
use serde_json::{Map, Value};

/// A field of a plan, and the rule its value breaks.
#[derive(Clone, Debug, Serialize, PartialEq, Eq)]
pub struct Refusal {
    pub field: String,
    pub rule: String,
}

/// Every refusal of one plan.
#[derive(Debug, Default)]
pub struct Refusals(pub Vec<Refusal>);

impl Refusals {
    pub fn refuse(&mut self, field: impl Into<String>, rule: impl Into<String>) {
        self.0.push(Refusal {
            field: field.into(),
            rule: rule.into(),
        });
    }

    /// The value, or its refusal noted under `field` (`None`).
    pub fn note<T>(&mut self, field: &str, checked: Result<T, String>) -> Option<T> {
        checked.map_err(|rule| self.refuse(field, rule)).ok()
    }

    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// Every refusal in one line each, `field: rule`.
    pub fn said(&self) -> String {
        let lines: Vec<String> = self
            .0
            .iter()
            .map(|r| format!("{}: {}", r.field, r.rule))
            .collect();
        lines.join("\n")
    }
}

/// The name among `known` nearest `name` (by edit distance), where one is near enough to
/// be what was meant.
pub fn nearest<'a>(name: &str, known: impl IntoIterator<Item = &'a str>) -> Option<&'a str> {
    known
        .into_iter()
        .map(|k| (distance(name, k), k))
        .filter(|&(d, k)| d <= 2.max(k.chars().count() / 3))
        .min_by_key(|&(d, _)| d)
        .map(|(_, k)| k)
}

/// The Levenshtein distance between two names.
fn distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut diagonal = row[0];
        row[0] = i + 1;
        for (j, &cb) in b.iter().enumerate() {
            let above = row[j + 1];
            row[j + 1] = (diagonal + usize::from(ca != cb))
                .min(row[j] + 1)
                .min(above + 1);
            diagonal = above;
        }
    }
    row[b.len()]
}

/// A table of a plan, read field by field; what is wrong is noted under `prefix.FIELD`.
pub struct Fields<'t, 'r> {
    table: &'t Map<String, Value>,
    prefix: String,
    known: Vec<&'static str>,
    refusals: &'r mut Refusals,
}

impl<'t, 'r> Fields<'t, 'r> {
    /// The table `value`, or its refusal noted under `prefix` (`None`).
    pub fn of(value: &'t Value, prefix: &str, refusals: &'r mut Refusals) -> Option<Self> {
        match value.as_object() {
            Some(table) => Some(Fields {
                table,
                prefix: prefix.to_string(),
                known: Vec::new(),
                refusals,
            }),
            None => {
                refusals.refuse(prefix, format!("must be a table, got {}", shown(value)));
                None
            }
        }
    }

    /// The field's full name.
    pub fn field(&self, key: &str) -> String {
        format!("{}.{key}", self.prefix)
    }

    pub fn refuse(&mut self, key: &str, rule: impl Into<String>) {
        let field = self.field(key);
        self.refusals.refuse(field, rule);
    }

    /// The refusals noted so far, for checks beyond one field's.
    pub fn refusals(&mut self) -> &mut Refusals {
        self.refusals
    }

    /// The field's value, where given (`null` counts as not given).
    pub fn get(&mut self, key: &'static str) -> Option<&'t Value> {
        self.known.push(key);
        self.table.get(key).filter(|v| !v.is_null())
    }

    /// A value that `read` turns into a T, or its refusal noted.
    fn read<T>(
        &mut self,
        key: &'static str,
        read: impl FnOnce(&Value) -> Result<T, String>,
    ) -> Option<T> {
        let value = self.get(key)?;
        match read(value) {
            Ok(v) => Some(v),
            Err(rule) => {
                self.refuse(key, rule);
                None
            }
        }
    }

    /// A field that must be given: its refusal noted where it is missing.
    pub fn required<T>(&mut self, key: &'static str, what: &str, value: Option<T>) -> Option<T> {
        if value.is_none() && self.table.get(key).is_none_or(Value::is_null) {
            self.refuse(key, format!("missing: give {what}"));
        }
        value
    }

    pub fn text(&mut self, key: &'static str) -> Option<String> {
        self.read(key, |v| match v.as_str() {
            Some(s) if !s.is_empty() => Ok(s.to_string()),
            _ => Err(format!("must be a name, got {}", shown(v))),
        })
    }

    pub fn number(&mut self, key: &'static str) -> Option<f64> {
        self.read(key, |v| match v.as_f64() {
            Some(x) if x.is_finite() && !v.is_boolean() => Ok(x),
            _ => Err(format!("must be a finite number, got {}", shown(v))),
        })
    }

    /// A whole number in [low, high].
    pub fn whole(&mut self, key: &'static str, low: usize, high: usize) -> Option<usize> {
        self.read(key, |v| match v.as_u64() {
            Some(n) if (low as u64..=high as u64).contains(&n) => Ok(n as usize),
            _ => Err(format!(
                "must be a whole number in [{low}, {high}], got {}",
                shown(v)
            )),
        })
    }

    pub fn boolean(&mut self, key: &'static str) -> Option<bool> {
        self.read(key, |v| {
            v.as_bool()
                .ok_or_else(|| format!("must be true or false, got {}", shown(v)))
        })
    }

    /// A list of names.
    pub fn names(&mut self, key: &'static str) -> Option<Vec<String>> {
        self.read(key, |v| {
            let names: Option<Vec<String>> = v.as_array().and_then(|items| {
                items
                    .iter()
                    .map(|i| i.as_str().filter(|s| !s.is_empty()).map(str::to_string))
                    .collect()
            });
            names.ok_or_else(|| format!("must be a list of names, got {}", shown(v)))
        })
    }

    /// The list at `key`: its items, each with its field's name.
    pub fn items(&mut self, key: &'static str) -> Vec<(String, &'t Value)> {
        let field = self.field(key);
        match self.get(key) {
            None => Vec::new(),
            Some(Value::Array(items)) => items
                .iter()
                .enumerate()
                .map(|(k, v)| (format!("{field}[{k}]"), v))
                .collect(),
            Some(other) => {
                self.refusals
                    .refuse(field, format!("must be a list, got {}", shown(other)));
                Vec::new()
            }
        }
    }

    /// Every field not read is unknown: each refused with the nearest known name, or with
    /// its new name where `renamed` gives one.
    pub fn finish(self, renamed: &[(&str, &str)]) {
        for key in self.table.keys() {
            if self.known.contains(&key.as_str()) {
                continue;
            }
            let rule = match renamed.iter().find(|(old, _)| old == key) {
                Some((_, new)) => format!("unknown field: it is called {new} now"),
                None => match nearest(key, self.known.iter().copied()) {
                    Some(near) => format!("unknown field: did you mean {near}?"),
                    None => format!("unknown field (the fields are: {})", self.known.join(", ")),
                },
            };
            self.refusals.refuse(format!("{}.{key}", self.prefix), rule);
        }
    }
}

/// A value as a user would write it in a message.
pub fn shown(value: &Value) -> String {
    match value {
        Value::String(s) => format!("the string {s:?}"),
        other => other.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn every_mistake_of_a_table_is_noted_with_its_field() {
        let value = json!({"state": 3, "advance": "2π", "samples": 4, "stpo": 1,
                           "period": 6.5, "keep": ["a", 5]});
        let mut refusals = Refusals::default();
        let mut fields = Fields::of(&value, "cycle", &mut refusals).unwrap();
        assert_eq!(fields.text("state"), None);
        assert_eq!(fields.number("advance"), None);
        assert_eq!(fields.whole("samples", 8, 1 << 20), None);
        assert_eq!(fields.names("keep"), None);
        assert_eq!(fields.boolean("stop"), None);
        assert_eq!(fields.text("absent"), None);
        let missing = fields.number("modes");
        fields.required("modes", "a number", missing);
        fields.finish(&[("period", "advance")]);
        let said: Vec<(&str, &str)> = refusals
            .0
            .iter()
            .map(|r| (r.field.as_str(), r.rule.as_str()))
            .collect();
        assert_eq!(
            said,
            [
                ("cycle.state", "must be a name, got 3"),
                (
                    "cycle.advance",
                    "must be a finite number, got the string \"2π\""
                ),
                (
                    "cycle.samples",
                    "must be a whole number in [8, 1048576], got 4"
                ),
                ("cycle.keep", "must be a list of names, got [\"a\",5]"),
                ("cycle.modes", "missing: give a number"),
                ("cycle.period", "unknown field: it is called advance now"),
                ("cycle.stpo", "unknown field: did you mean stop?"),
            ]
        );
    }

    #[test]
    fn the_nearest_name_is_offered_only_when_near() {
        assert_eq!(
            nearest("tolerence", ["tolerance", "stop"]),
            Some("tolerance")
        );
        assert_eq!(nearest("xyz", ["tolerance", "stop"]), None);
    }
}
