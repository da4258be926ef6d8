//! 100STYLE's `Frame_Cuts.csv`: the usable frame window of every take (each starts with a
//! calibration pose and a walk-in). One row per style, a `<TYPE>_START`, `<TYPE>_STOP` column
//! pair per take type (`BW` backward, `SW` sideways, `ID` idle, `TR1` transitions…), `N/A`
//! where the style lacks the take; the file of style `Angry`, type `BW` is `Angry_BW.bvh`.

use crate::error::{Error, Result};
use crate::limits::quote;
use std::collections::HashMap;

/// `file name → [start, stop)` source frames for every take the CSV lists.
///
/// # Errors
/// No header, a header without `STYLE_NAME` first or with unpaired `_START`/`_STOP` columns, or
/// a cell that is neither a frame number nor `N/A` (the message names the line).
pub fn parse(text: &str) -> Result<HashMap<String, [usize; 2]>> {
    let mut lines = text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty());
    let (_, header) = lines.next().ok_or_else(|| Error::config("Frame_Cuts.csv: empty file"))?;
    let columns: Vec<&str> = header.split(',').map(str::trim).collect();
    if columns.first() != Some(&"STYLE_NAME") {
        return Err(Error::config("Frame_Cuts.csv: the header must start with STYLE_NAME"));
    }
    let mut types = Vec::new();
    for pair in columns[1..].chunks(2) {
        match pair {
            [a, b] if a.strip_suffix("_START").is_some() && a.strip_suffix("_START") == b.strip_suffix("_STOP") => {
                types.push(a.strip_suffix("_START").unwrap())
            }
            _ => {
                return Err(Error::config(format!(
                    "Frame_Cuts.csv: expected <TYPE>_START,<TYPE>_STOP column pairs, found '{}'",
                    quote(&pair.join(","))
                )))
            }
        }
    }
    let mut cuts = HashMap::new();
    for (i, line) in lines {
        let cells: Vec<&str> = line.split(',').map(str::trim).collect();
        let number = |k: usize| -> Result<Option<usize>> {
            match cells.get(k).copied().unwrap_or("N/A") {
                "N/A" | "" => Ok(None),
                v => v.parse().map(Some).map_err(|_| {
                    Error::config(format!("Frame_Cuts.csv:{}: '{}' is not a frame number", i + 1, quote(v)))
                }),
            }
        };
        for (t, kind) in types.iter().enumerate() {
            if let (Some(start), Some(stop)) = (number(1 + 2 * t)?, number(2 + 2 * t)?) {
                if stop > start {
                    cuts.insert(format!("{}_{kind}.bvh", cells[0]), [start, stop]);
                }
            }
        }
    }
    Ok(cuts)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_windows_and_skips_missing_takes() {
        let csv = "STYLE_NAME,BW_START,BW_STOP,TR2_START,TR2_STOP\nAngry,535,4538,N/A,N/A\nAkimbo,388,7899,10,20\n";
        let cuts = parse(csv).unwrap();
        assert_eq!(cuts["Angry_BW.bvh"], [535, 4538]);
        assert_eq!(cuts["Akimbo_TR2.bvh"], [10, 20]);
        assert!(!cuts.contains_key("Angry_TR2.bvh"));
        assert!(parse("STYLE,A_START,A_STOP\n").is_err());
        assert!(parse("STYLE_NAME,A_START,B_STOP\n").is_err());
        assert!(parse("STYLE_NAME,A_START,A_STOP\nX,1,zz\n").unwrap_err().to_string().contains(":2:"));
    }
}
