//! Source columns as a mapping file names them: a plain column (`r_s_rad`), an element of a
//! column holding an array (`q[3]`, `markers[0][1]`: a cell such as `"[0.1 0.2 0.3]"` or
//! `"[[0.1, 0.2], [0.3, 0.4]]"`, as numpy and pandas write arrays), or a whole array column
//! standing for its first n elements (`robot1 = "q"`). [`ColumnRef`] is one such name, found in
//! an input header by [`ColumnRef::locate`] and read from a row by [`LocatedColumn::value`].

use serde::Deserialize;

/// One column or a list of columns as written in a map: `"q"` (an array column, its elements
/// taken in order) or `["a", "b", "c"]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(untagged)]
pub(super) enum ColumnList {
    /// One name: an array column whose first n elements are the n values.
    One(String),
    /// One name per value.
    Many(Vec<String>),
}

impl ColumnList {
    /// The `n` column references of the list: a list of exactly `n` names, or one name whose
    /// elements `[0]` … `[n−1]` are meant. Errors: a list of another length, a malformed name
    /// (the message names the key `key` and says what `n` values it needs, `what`).
    pub(super) fn expand(&self, n: usize, key: &str, what: &str) -> Result<Vec<ColumnRef>, String> {
        match self {
            ColumnList::One(name) => {
                let base = ColumnRef::parse(name, key)?;
                Ok((0..n)
                    .map(|i| {
                        let mut c = base.clone();
                        c.written = format!("{name}[{i}]");
                        c.index.push(i);
                        c
                    })
                    .collect())
            }
            ColumnList::Many(names) if names.len() == n => names
                .iter()
                .map(|name| ColumnRef::parse(name, key))
                .collect(),
            ColumnList::Many(names) => Err(format!(
                "{key} names {} column(s) but needs {n} ({what}): list {n} columns, or name one \
                 column holding an array of them (e.g. {key} = \"q\" for q[0] … q[{}])",
                names.len(),
                n.saturating_sub(1)
            )),
        }
    }
}

/// A source column as the map names it: the column `base` and the indices into the array its
/// cells hold (none for a plain number column).
#[derive(Debug, Clone, PartialEq, Eq)]
pub(super) struct ColumnRef {
    /// The name as written (`markers[0][1]`), for messages.
    pub(super) written: String,
    /// The header column.
    pub(super) base: String,
    /// Indices into the cell's (nested) array, outermost first.
    pub(super) index: Vec<usize>,
}

impl ColumnRef {
    /// Parses `name`: `column` or `column[i][j]…` (indices from 0). Errors name the key `key`.
    pub(super) fn parse(name: &str, key: &str) -> Result<ColumnRef, String> {
        let bad = |why: &str| {
            format!("{key}: `{name}` {why}; write a column name, or `name[i]` / `name[i][j]` for an element of a column holding an array (indices from 0)")
        };
        let (base, mut rest) = match name.find('[') {
            Some(k) => (&name[..k], &name[k..]),
            None => (name, ""),
        };
        if base.is_empty() {
            return Err(bad("has no column name"));
        }
        let mut index = Vec::new();
        while !rest.is_empty() {
            let Some(close) = rest.find(']') else {
                return Err(bad("has an unclosed `[`"));
            };
            let i: usize = rest[1..close]
                .trim()
                .parse()
                .map_err(|_| bad("has an index that is not a whole number ≥ 0"))?;
            index.push(i);
            rest = &rest[close + 1..];
            if !(rest.is_empty() || rest.starts_with('[')) {
                return Err(bad("has text after an index"));
            }
        }
        Ok(ColumnRef {
            written: name.to_string(),
            base: base.to_string(),
            index,
        })
    }

    /// Finds the column in `headers`: the name as written when the header has it (a column
    /// literally named `q[3]`), else its base column with the indices. Errors: neither is there
    /// (the message lists the header).
    pub(super) fn locate(&self, headers: &csv::StringRecord) -> Result<LocatedColumn, String> {
        let pos = |name: &str| headers.iter().position(|h| h == name);
        if let Some(i) = pos(&self.written) {
            return Ok(LocatedColumn {
                column: i,
                written: self.written.clone(),
                index: Vec::new(),
            });
        }
        match pos(&self.base) {
            Some(i) => Ok(LocatedColumn {
                column: i,
                written: self.written.clone(),
                index: self.index.clone(),
            }),
            None => Err(format!(
                "line 1: no column `{}` (named in the map{}); the header has: {}",
                self.base,
                if self.index.is_empty() {
                    String::new()
                } else {
                    format!(" as `{}`", self.written)
                },
                kinematics::input::cap_echo(&headers.iter().collect::<Vec<_>>().join(","))
            )),
        }
    }
}

/// A [`ColumnRef`] found in an input header.
#[derive(Debug, Clone)]
pub(super) struct LocatedColumn {
    column: usize,
    written: String,
    index: Vec<usize>,
}

impl LocatedColumn {
    /// The header position of the column.
    pub(super) fn position(&self) -> usize {
        self.column
    }

    /// The number in this column of `record`: `Ok(None)` for an empty cell or a NaN (the caller
    /// decides whether that skips the row or is an error), `Ok(Some(x))` for a finite number (an
    /// infinity is `None` too). Errors, naming the column as the map wrote it and the fix: a
    /// cell holding an array where the map names no element, a cell that is not a number, an
    /// index into a cell that holds no array or past its end, too few indices.
    pub(super) fn value(&self, record: &csv::StringRecord) -> Result<Option<f64>, String> {
        let cell = record.get(self.column).unwrap_or("").trim();
        if cell.is_empty() {
            return Ok(None);
        }
        let name = &self.written;
        let shown = shorten(cell);
        if self.index.is_empty() {
            if cell.starts_with('[') || cell.starts_with('(') {
                return Err(format!(
                    "column `{name}` holds an array (`{shown}`): name one element in the map, e.g. \
                     `{name}[0]` (`{name}[0][1]` in an array of arrays), or `\"{name}\"` alone for a \
                     [joints] list or [tracker] columns that are its elements in order"
                ));
            }
            return match cell.parse::<f64>() {
                Ok(x) => Ok(x.is_finite().then_some(x)),
                Err(_) => Err(format!("column `{name}`: `{shown}` is not a number")),
            };
        }
        let array = Nested::parse(cell).map_err(|why| {
            format!("column `{name}`: `{shown}` is not an array of numbers ({why})")
        })?;
        let mut at = &array;
        for (depth, &i) in self.index.iter().enumerate() {
            match at {
                Nested::List(items) => {
                    at = items.get(i).ok_or_else(|| {
                        format!(
                            "column `{name}`: index {i} at depth {} is past the end of `{shown}` ({} element(s), indices 0..{})",
                            depth + 1,
                            items.len(),
                            items.len().saturating_sub(1)
                        )
                    })?;
                }
                Nested::Number(_) => {
                    return Err(format!(
                        "column `{name}`: `{shown}` has fewer levels than the {} index(es) given",
                        self.index.len()
                    ))
                }
            }
        }
        match at {
            Nested::Number(x) => Ok(x.is_finite().then_some(*x)),
            Nested::List(_) => Err(format!(
                "column `{name}`: that element of `{shown}` is itself an array; add an index (e.g. `{name}[0]`)"
            )),
        }
    }
}

/// A cell's text cut to 60 characters for messages.
fn shorten(cell: &str) -> String {
    let flat: String = cell
        .chars()
        .map(|c| if c.is_whitespace() { ' ' } else { c })
        .collect();
    if flat.chars().count() > 60 {
        format!("{}…", flat.chars().take(60).collect::<String>())
    } else {
        flat
    }
}

/// A cell's (nested) array of numbers.
#[derive(Debug, Clone, PartialEq)]
enum Nested {
    Number(f64),
    List(Vec<Nested>),
}

impl Nested {
    /// Parses `[a b c]`, `[a, b, c]`, `[[a b] [c d]]` (numpy's and pandas' text; brackets or
    /// parentheses, separators spaces, newlines or commas; `nan`, `inf` as Rust reads them).
    fn parse(text: &str) -> Result<Nested, String> {
        let mut tokens = Vec::new();
        let mut word = String::new();
        for c in text.chars() {
            match c {
                '[' | ']' | '(' | ')' | ',' => {
                    if !word.is_empty() {
                        tokens.push(std::mem::take(&mut word));
                    }
                    tokens.push(c.to_string());
                }
                c if c.is_whitespace() => {
                    if !word.is_empty() {
                        tokens.push(std::mem::take(&mut word));
                    }
                }
                c => word.push(c),
            }
        }
        if !word.is_empty() {
            tokens.push(word);
        }
        let mut pos = 0;
        let value = Self::item(&tokens, &mut pos)?;
        if pos != tokens.len() {
            return Err(format!("unexpected `{}` after the array", tokens[pos]));
        }
        match value {
            Nested::List(_) => Ok(value),
            Nested::Number(_) => Err("a number, not an array".into()),
        }
    }

    fn item(tokens: &[String], pos: &mut usize) -> Result<Nested, String> {
        let Some(t) = tokens.get(*pos) else {
            return Err("it ends too early".into());
        };
        *pos += 1;
        match t.as_str() {
            "[" | "(" => {
                let close = if t == "[" { "]" } else { ")" };
                let mut items = Vec::new();
                loop {
                    match tokens.get(*pos).map(String::as_str) {
                        None => return Err(format!("no closing `{close}`")),
                        Some(c) if c == close => {
                            *pos += 1;
                            return Ok(Nested::List(items));
                        }
                        Some(",") => *pos += 1,
                        Some(_) => items.push(Self::item(tokens, pos)?),
                    }
                }
            }
            w => w
                .parse::<f64>()
                .map(Nested::Number)
                .map_err(|_| format!("`{w}` is not a number")),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(cells: &[&str]) -> csv::StringRecord {
        csv::StringRecord::from(cells.to_vec())
    }

    fn located(name: &str, headers: &[&str]) -> LocatedColumn {
        ColumnRef::parse(name, "k")
            .unwrap()
            .locate(&record(headers))
            .unwrap()
    }

    /// numpy (`[0.1 0.2 0.3]`, 2-D over lines), pandas lists (`[0.1, 0.2]`) and tuples are
    /// indexed; an element past the end, too many or too few indices and an array in an
    /// unindexed column are errors naming the column.
    #[test]
    fn array_cells_are_indexed_or_refused_by_name() {
        let h = ["id", "q", "markers"];
        let row = record(&["7", "[0.1 0.2  -3e-1]", "[[1.5, 2, 3]\n [4 5 nan]]"]);
        assert_eq!(located("q[2]", &h).value(&row), Ok(Some(-0.3)));
        assert_eq!(located("markers[1][0]", &h).value(&row), Ok(Some(4.0)));
        assert_eq!(located("markers[1][2]", &h).value(&row), Ok(None));
        assert_eq!(located("id", &h).value(&row), Ok(Some(7.0)));
        let e = located("q", &h).value(&row).unwrap_err();
        assert!(
            e.starts_with("column `q` holds an array") && e.contains("`q[0]`"),
            "{e}"
        );
        let e = located("q[3]", &h).value(&row).unwrap_err();
        assert!(e.contains("index 3 at depth 1 is past the end"), "{e}");
        let e = located("markers[0]", &h).value(&row).unwrap_err();
        assert!(e.contains("is itself an array"), "{e}");
        let e = located("q[0][0]", &h).value(&row).unwrap_err();
        assert!(e.contains("fewer levels"), "{e}");
        let e = located("id[0]", &h).value(&row).unwrap_err();
        assert!(e.contains("not an array of numbers"), "{e}");
        assert_eq!(
            located("q[1]", &h).value(&record(&["", "(1, 2)", ""])),
            Ok(Some(2.0))
        );
        assert_eq!(located("q[1]", &h).value(&record(&["", "", ""])), Ok(None));
    }

    /// One name stands for its first n elements; a list must have n names; malformed names
    /// and missing columns are named.
    #[test]
    fn column_lists_expand_and_errors_name_the_key() {
        let one = ColumnList::One("markers[1]".into()).expand(3, "[tracker] columns", "x, y, z");
        let names: Vec<String> = one.unwrap().into_iter().map(|c| c.written).collect();
        assert_eq!(names, ["markers[1][0]", "markers[1][1]", "markers[1][2]"]);
        let e = ColumnList::Many(vec!["a".into()])
            .expand(3, "[tracker] columns", "x, y, z")
            .unwrap_err();
        assert!(
            e.starts_with("[tracker] columns names 1 column(s) but needs 3"),
            "{e}"
        );
        for bad in ["q[", "q[x]", "[0]", "q[0]x"] {
            assert!(ColumnRef::parse(bad, "k").is_err(), "{bad}");
        }
        let e = ColumnRef::parse("m[0][1]", "k")
            .unwrap()
            .locate(&record(&["a", "b"]))
            .unwrap_err();
        assert_eq!(
            e,
            "line 1: no column `m` (named in the map as `m[0][1]`); the header has: a,b"
        );
        // A header that holds the written name itself takes it as a plain column.
        let c = located("q[3]", &["q[3]"]);
        assert_eq!(c.value(&record(&["0.5"])), Ok(Some(0.5)));
    }
}
