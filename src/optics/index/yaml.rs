//! The parser of refractiveindex.info YAML files (`DATA` entries of
//! `tabulated n`, `tabulated k`, `tabulated nk` and `formula 1`–`formula 9`)
//! into the parts of an [`IndexSpectrum`](super::IndexSpectrum); errors
//! name the file, the entry and, where known, the line.

use super::dispersion::{Correction, Formula, RealPart, RealSource, Table, MAX_COEFFICIENTS};
use super::error::IndexError;
use serde::Deserialize;
use serde_yaml_ng::Value;

#[derive(Deserialize)]
pub(super) struct RawFile {
    #[serde(rename = "DATA")]
    pub(super) data: Option<Vec<RawEntry>>,
}

#[derive(Deserialize)]
pub(super) struct RawEntry {
    #[serde(rename = "type")]
    pub(super) kind: Option<Value>,
    pub(super) data: Option<Value>,
    pub(super) coefficients: Option<Value>,
    #[serde(alias = "range")]
    pub(super) wavelength_range: Option<Value>,
}

/// Which quantities a tabulated entry's columns hold.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum Columns {
    Nk,
    N,
    K,
}

pub(super) enum Parsed {
    Table { columns: Columns, wavelength_um: Vec<f64>, n: Vec<f64>, k: Vec<f64> },
    Formula(Formula),
}

pub(super) struct Ctx<'a> {
    pub(super) text: &'a str,
    pub(super) file: &'a str,
}

impl Ctx<'_> {
    pub(super) fn format(&self, message: String) -> IndexError {
        IndexError::Format { file: self.file.to_string(), message }
    }
}

/// The real part n and, if the file has one, the table of κ of the
/// spectrum in `text` (the file `file`).
pub(super) fn parse_spectrum(text: &str, file: &str) -> Result<(RealPart, Option<Table>), IndexError> {
    let raw: RawFile = serde_yaml_ng::from_str(text)
        .map_err(|e| IndexError::Yaml { file: file.to_string(), message: e.to_string() })?;
    let ctx = Ctx { text, file };
    let entries = raw.data.ok_or_else(|| ctx.format("no DATA key".to_string()))?;
    if entries.is_empty() {
        return Err(ctx.format("DATA has no entries".to_string()));
    }
    let mut n: Option<RealSource> = None;
    let mut k: Option<Table> = None;
    // Ordinals among entries having a `data:` / `coefficients:` key, used to
    // find file line numbers for error messages.
    let (mut data_ordinal, mut coefficient_ordinal) = (0usize, 0usize);
    for (i, entry) in entries.iter().enumerate() {
        let parsed = parse_entry(&ctx, i + 1, entry, data_ordinal, coefficient_ordinal)?;
        data_ordinal += usize::from(entry.data.is_some());
        coefficient_ordinal += usize::from(entry.coefficients.is_some());
        match parsed {
            Parsed::Formula(f) => {
                if n.is_none() {
                    n = Some(RealSource::Formula(f));
                }
            }
            Parsed::Table { columns, wavelength_um, n: nv, k: kv } => {
                if matches!(columns, Columns::Nk | Columns::N) && n.is_none() {
                    n = Some(RealSource::Table(Table { wavelength_um: wavelength_um.clone(), value: nv }));
                }
                if matches!(columns, Columns::Nk | Columns::K) && k.is_none() {
                    k = Some(Table { wavelength_um, value: kv });
                }
            }
        }
    }
    let n = n.ok_or_else(|| IndexError::NoRealPart { file: file.to_string() })?;
    Ok((RealPart { source: n, correction: Correction::None }, k))
}

pub(super) fn scalar_text(v: &Value) -> Option<String> {
    match v {
        Value::String(s) => Some(s.clone()),
        Value::Number(x) => Some(x.to_string()),
        _ => None,
    }
}

pub(super) fn parse_entry(
    ctx: &Ctx<'_>,
    index: usize,
    entry: &RawEntry,
    data_ordinal: usize,
    coefficient_ordinal: usize,
) -> Result<Parsed, IndexError> {
    let kind = entry
        .kind
        .as_ref()
        .and_then(scalar_text)
        .ok_or_else(|| ctx.format(format!("DATA entry {index} has no 'type' string")))?;
    let normalized = kind.split_whitespace().collect::<Vec<_>>().join(" ").to_ascii_lowercase();
    let entry_name = format!("DATA entry {index} ({normalized})");
    let unknown = || IndexError::UnknownType {
        file: ctx.file.to_string(),
        location: format!("DATA entry {index}"),
        kind: kind.clone(),
    };
    let columns = match normalized.as_str() {
        "tabulated nk" => Some(Columns::Nk),
        "tabulated n" => Some(Columns::N),
        "tabulated k" => Some(Columns::K),
        _ => None,
    };
    if let Some(columns) = columns {
        let data = entry
            .data
            .as_ref()
            .and_then(scalar_text)
            .ok_or_else(|| ctx.format(format!("{entry_name} has no 'data' string")))?;
        return parse_table(ctx, &entry_name, columns, &data, data_ordinal);
    }
    let number = normalized.strip_prefix("formula ").ok_or_else(unknown)?;
    let kind_number: u8 = match number.parse() {
        Ok(v @ 1..=9) => v,
        _ => return Err(unknown()),
    };
    let coefficients_text = entry
        .coefficients
        .as_ref()
        .and_then(scalar_text)
        .ok_or_else(|| ctx.format(format!("{entry_name} has no 'coefficients' string")))?;
    let coefficient_location = match find_key_line(ctx.text, "coefficients", coefficient_ordinal) {
        Some(line) => format!("line {} ({entry_name} coefficients)", line + 1),
        None => format!("{entry_name} coefficients"),
    };
    let mut c = [0.0; 17];
    let max = MAX_COEFFICIENTS[usize::from(kind_number - 1)];
    let mut count = 0;
    for token in coefficients_text.split_whitespace() {
        let value = parse_number(ctx, &coefficient_location, token)?;
        if !value.is_finite() {
            return Err(invalid(ctx, &coefficient_location, "coefficient", value, "finite"));
        }
        if count >= max {
            return Err(ctx.format(format!(
                "{coefficient_location}: formula {kind_number} takes at most {max} coefficients, found {}",
                coefficients_text.split_whitespace().count()
            )));
        }
        c[count] = value;
        count += 1;
    }
    if count == 0 {
        return Err(ctx.format(format!("{coefficient_location}: no coefficients")));
    }
    // Formulas 1, 2, 3, 5 and 6 are C0 plus terms of two coefficients each:
    // an even count leaves the last term without its second one (taken as
    // 0, it silently changes the formula, e.g. Sellmeier-2's pole to λ² = 0).
    if [1, 2, 3, 5, 6].contains(&kind_number) && count % 2 == 0 {
        return Err(ctx.format(format!(
            "{coefficient_location}: formula {kind_number} takes C0 and then pairs of coefficients (an odd count: 1, \
             3, 5, …), found {count}: the last term lacks its second coefficient; give it (0 if it is meant)"
        )));
    }
    let range_text = entry
        .wavelength_range
        .as_ref()
        .and_then(scalar_text)
        .ok_or_else(|| ctx.format(format!("{entry_name} has no 'wavelength_range' string")))?;
    let range_location = format!("{entry_name} wavelength_range");
    let values =
        range_text.split_whitespace().map(|t| parse_number(ctx, &range_location, t)).collect::<Result<Vec<_>, _>>()?;
    let &[lo, hi] = values.as_slice() else {
        return Err(ctx.format(format!("{range_location}: expected two numbers 'min max' in µm, found '{range_text}'")));
    };
    for v in [lo, hi] {
        if !(v.is_finite() && v > 0.0) {
            return Err(invalid(ctx, &range_location, "wavelength (µm)", v, "finite and positive"));
        }
    }
    if lo >= hi {
        return Err(ctx.format(format!("{range_location}: minimum {lo} µm is not below maximum {hi} µm")));
    }
    Ok(Parsed::Formula(Formula { kind: kind_number, c, range_um: (lo, hi) }))
}

pub(super) fn parse_number(ctx: &Ctx<'_>, location: &str, token: &str) -> Result<f64, IndexError> {
    token.parse::<f64>().map_err(|_| IndexError::BadNumber {
        file: ctx.file.to_string(),
        location: location.to_string(),
        token: token.to_string(),
    })
}

pub(super) fn invalid(ctx: &Ctx<'_>, location: &str, quantity: &str, value: f64, requirement: &str) -> IndexError {
    IndexError::InvalidValue {
        file: ctx.file.to_string(),
        location: location.to_string(),
        quantity: quantity.to_string(),
        value,
        requirement: requirement.to_string(),
    }
}

pub(super) fn parse_table(
    ctx: &Ctx<'_>,
    entry_name: &str,
    columns: Columns,
    data: &str,
    data_ordinal: usize,
) -> Result<Parsed, IndexError> {
    let width = if columns == Columns::Nk { 3 } else { 2 };
    let header = find_key_line(ctx.text, "data", data_ordinal);
    let file_lines: Vec<&str> = if header.is_some() { ctx.text.lines().collect() } else { Vec::new() };
    // "line L (entry)" when the table line is found verbatim in the file
    // right after the `data: |` header, else "entry, table line i".
    let location = |i: usize, line: &str| -> String {
        if let Some(h) = header
            && file_lines.get(h + 1 + i).map(|l| l.trim()) == Some(line.trim())
        {
            return format!("line {} ({entry_name})", h + 2 + i);
        }
        format!("{entry_name}, table line {}", i + 1)
    };
    let (mut wavelength_um, mut n, mut k) = (Vec::new(), Vec::new(), Vec::new());
    for (i, line) in data.lines().enumerate() {
        let tokens: Vec<&str> = line.split_whitespace().collect();
        if tokens.is_empty() {
            continue;
        }
        if tokens.len() != width {
            return Err(ctx.format(format!(
                "{}: expected {width} numbers per row, found {}: '{}'",
                location(i, line),
                tokens.len(),
                line.trim()
            )));
        }
        let mut row = [0.0; 3];
        for (slot, token) in row.iter_mut().zip(&tokens) {
            *slot = parse_number(ctx, &location(i, line), token)?;
        }
        let w = row[0];
        if !(w.is_finite() && w > 0.0) {
            return Err(invalid(ctx, &location(i, line), "wavelength (µm)", w, "finite and positive"));
        }
        let (nv, kv) = match columns {
            Columns::Nk => (Some(row[1]), Some(row[2])),
            Columns::N => (Some(row[1]), None),
            Columns::K => (None, Some(row[1])),
        };
        if let Some(v) = nv {
            if !(v.is_finite() && v >= 0.0) {
                return Err(invalid(ctx, &location(i, line), "n", v, "finite and ≥ 0"));
            }
            n.push(v);
        }
        if let Some(v) = kv {
            if !(v.is_finite() && v >= 0.0) {
                return Err(invalid(ctx, &location(i, line), "k", v, "finite and ≥ 0"));
            }
            k.push(v);
        }
        if let Some(&previous) = wavelength_um.last()
            && w <= previous
        {
            return Err(IndexError::NonIncreasing {
                file: ctx.file.to_string(),
                location: location(i, line),
                previous_um: previous,
                wavelength_um: w,
            });
        }
        wavelength_um.push(w);
    }
    if wavelength_um.len() < 2 {
        return Err(IndexError::TooFewRows {
            file: ctx.file.to_string(),
            location: entry_name.to_string(),
            rows: wavelength_um.len(),
        });
    }
    Ok(Parsed::Table { columns, wavelength_um, n, k })
}

/// 0-based line index of the `ordinal`-th (0-based) line whose content
/// starts with `key:` (after indentation and an optional `- `). Best effort,
/// only used to put file line numbers into error messages.
pub(super) fn find_key_line(text: &str, key: &str, ordinal: usize) -> Option<usize> {
    text.lines()
        .enumerate()
        .filter(|(_, line)| {
            let t = line.trim_start();
            let t = t.strip_prefix('-').map_or(t, str::trim_start);
            t.strip_prefix(key).is_some_and(|rest| rest.starts_with(':'))
        })
        .nth(ordinal)
        .map(|(i, _)| i)
}
