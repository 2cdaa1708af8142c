//! A reader for CGATS.17 text files such as Argyll's `.ti3` characterisation data: keyword
//! lines, a `BEGIN_DATA_FORMAT … END_DATA_FORMAT` list of field names and a
//! `BEGIN_DATA … END_DATA` table. Only what a press characterisation needs: the CMYK and
//! XYZ columns of every patch.

use std::path::Path;

use crate::error::{Error, Result};

/// One measured patch: nominal ink amounts (0..1) and the measured XYZ (Y of the perfect
/// white = 100, D50).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Patch {
    /// Cyan, magenta, yellow, black, as fractions 0..1.
    pub cmyk: [f64; 4],
    /// Measured tristimulus values.
    pub xyz: [f64; 3],
}

/// Parses a CGATS file's CMYK and XYZ columns. Errors name `source` and the line.
pub fn parse(text: &str, source: &Path) -> Result<Vec<Patch>> {
    let mut fields: Vec<String> = Vec::new();
    let mut in_format = false;
    let mut in_data = false;
    let mut cols: Option<[usize; 7]> = None;
    let mut patches = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let line_no = i + 1;
        let line = raw.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        if in_format {
            if line.starts_with("END_DATA_FORMAT") {
                in_format = false;
            } else {
                fields.extend(line.split_whitespace().map(str::to_ascii_uppercase));
            }
            continue;
        }
        if in_data {
            if line.starts_with("END_DATA") {
                in_data = false;
                continue;
            }
            let cols = cols.ok_or_else(|| {
                Error::parse(source, line_no, "data before a BEGIN_DATA_FORMAT section")
            })?;
            let toks: Vec<&str> = line.split_whitespace().collect();
            if toks.len() < fields.len() {
                return Err(Error::parse(
                    source,
                    line_no,
                    format!("{} values, the format has {}", toks.len(), fields.len()),
                ));
            }
            let mut v = [0f64; 7];
            for (k, &c) in cols.iter().enumerate() {
                v[k] = toks[c]
                    .trim_matches('"')
                    .parse()
                    .ok()
                    .filter(|x: &f64| x.is_finite())
                    .ok_or_else(|| {
                        Error::parse(
                            source,
                            line_no,
                            format!("'{}' is not a number ({})", toks[c], fields[c]),
                        )
                    })?;
            }
            // Ink amounts are percentages; measured XYZ cannot be negative.
            for (k, &x) in v.iter().enumerate() {
                let (lo, hi) = if k < 4 { (0.0, 100.0) } else { (0.0, f64::MAX) };
                if !(lo..=hi).contains(&x) {
                    let range = if k < 4 { "0 to 100" } else { "0 or more" };
                    return Err(Error::parse(
                        source,
                        line_no,
                        format!("{} is {x}: it must be {range}", fields[cols[k]]),
                    ));
                }
            }
            patches.push(Patch {
                cmyk: [v[0] / 100.0, v[1] / 100.0, v[2] / 100.0, v[3] / 100.0],
                xyz: [v[4], v[5], v[6]],
            });
            continue;
        }
        if line.starts_with("BEGIN_DATA_FORMAT") {
            in_format = true;
            fields.clear();
        } else if line.starts_with("BEGIN_DATA") {
            let find = |name: &str| fields.iter().position(|f| f == name);
            let names = [
                "CMYK_C", "CMYK_M", "CMYK_Y", "CMYK_K", "XYZ_X", "XYZ_Y", "XYZ_Z",
            ];
            let mut c = [0usize; 7];
            for (k, n) in names.iter().enumerate() {
                c[k] = find(n).ok_or_else(|| {
                    Error::parse(
                        source,
                        line_no,
                        format!("no {n} field: a press characterisation needs CMYK_C..CMYK_K and XYZ_X..XYZ_Z"),
                    )
                })?;
            }
            cols = Some(c);
            in_data = true;
        }
    }
    if patches.is_empty() {
        return Err(Error::parse(
            source,
            0,
            "no measured patches (BEGIN_DATA … END_DATA)",
        ));
    }
    Ok(patches)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_fields_in_any_order() {
        let text = "CTI3\nNUMBER_OF_FIELDS 8\nBEGIN_DATA_FORMAT\nSAMPLE_ID XYZ_X XYZ_Y XYZ_Z\nCMYK_C CMYK_M CMYK_Y CMYK_K\nEND_DATA_FORMAT\nBEGIN_DATA\n1 84.5 87.6 74.6 0 0 0 0\n2 1 1.5 1.2 100 100 100 100 # rich black\nEND_DATA\n";
        let p = parse(text, Path::new("t.ti3")).unwrap();
        assert_eq!(p.len(), 2);
        assert_eq!(p[0].xyz, [84.5, 87.6, 74.6]);
        assert_eq!(p[1].cmyk, [1.0; 4]);
    }

    #[test]
    fn missing_field_names_the_file() {
        let text = "BEGIN_DATA_FORMAT\nSAMPLE_ID LAB_L LAB_A LAB_B\nEND_DATA_FORMAT\nBEGIN_DATA\n1 2 3 4\nEND_DATA\n";
        let e = parse(text, Path::new("lab.ti3")).unwrap_err().to_string();
        // The field list is checked where the data begins (line 4).
        assert!(e.starts_with("lab.ti3:4: no CMYK_C"), "{e}");
    }
}
