//! The text rules of CSV input, apart from the streaming: the separator, fields with RFC 4180
//! quotes, the `# fs=` comment and the printed precision of a time.

use std::borrow::Cow;

/// The separator of a CSV line: `,`, else `;`, else tab (`,` when there is none).
pub(super) fn detect_delim(line: &str) -> char {
    [',', ';', '\t']
        .into_iter()
        .find(|&d| line.contains(d))
        .unwrap_or(',')
}

/// The fields of one line, trimmed, with RFC 4180 quotes removed: a quoted field may hold the
/// separator and doubled quotes (`"Acc, top"`, `"say ""hi"""`), as other tools write sensor ids
/// and, with every field quoted (pandas' `QUOTE_ALL`), numbers. Text outside the quotes of a
/// quoted field is kept as written; an unclosed quote runs to the end of the line.
pub(super) fn split_fields(line: &str, delim: char) -> Vec<Cow<'_, str>> {
    if !line.contains('"') {
        return line.split(delim).map(|f| Cow::Borrowed(f.trim())).collect();
    }
    let mut fields = Vec::new();
    let mut rest = line;
    loop {
        let trimmed = rest.trim_start();
        let (field, after) = match trimmed.strip_prefix('"') {
            Some(quoted) => {
                let mut value = String::new();
                let mut chars = quoted.char_indices();
                let mut end = quoted.len();
                while let Some((i, c)) = chars.next() {
                    if c != '"' {
                        value.push(c);
                    } else if quoted[i + 1..].starts_with('"') {
                        value.push('"');
                        chars.next();
                    } else {
                        end = i + 1;
                        break;
                    }
                }
                let tail = &quoted[end..];
                let stop = tail.find(delim).unwrap_or(tail.len());
                value.push_str(tail[..stop].trim_end());
                (Cow::Owned(value), &tail[stop..])
            }
            None => {
                let stop = trimmed.find(delim).unwrap_or(trimmed.len());
                (Cow::Borrowed(trimmed[..stop].trim()), &trimmed[stop..])
            }
        };
        fields.push(field);
        match after.strip_prefix(delim) {
            Some(next) => rest = next,
            None => return fields,
        }
    }
}

/// Whether a header field names the time column: `time` or `t`, any case.
pub(super) fn is_time_header(name: &str) -> bool {
    matches!(name.to_ascii_lowercase().as_str(), "time" | "t")
}

/// Whether a first line's fields are exactly `ids`, in any order, after an optional time column.
pub(super) fn names_the_channels(fields: &[Cow<'_, str>], ids: &[String]) -> bool {
    let channels = match fields.first() {
        Some(f) if is_time_header(f) => &fields[1..],
        _ => fields,
    };
    if ids.is_empty() || channels.len() != ids.len() {
        return false;
    }
    let mut a: Vec<&str> = channels.iter().map(|f| f.as_ref()).collect();
    let mut b: Vec<&str> = ids.iter().map(String::as_str).collect();
    a.sort_unstable();
    b.sort_unstable();
    a == b
}

/// The sample rate of a `# fs=51200` or `# fs: 51200` comment (anything may follow the number).
pub(super) fn parse_fs_comment(comment: &str) -> Option<f64> {
    let rest = comment.trim_start_matches('#').trim_start();
    let rest = rest
        .strip_prefix("fs")
        .or_else(|| rest.strip_prefix("FS"))?
        .trim_start();
    let rest = rest
        .strip_prefix('=')
        .or_else(|| rest.strip_prefix(':'))?
        .trim_start();
    let end = rest
        .find(|c: char| !(c.is_ascii_digit() || matches!(c, '.' | 'e' | 'E' | '+' | '-')))
        .unwrap_or(rest.len());
    rest[..end].parse().ok()
}

/// The step of the last printed digit of a number: `0.00025` → 1e-5, `2.5e-4` → 1e-5; an
/// integer (`0`, `3`) counts as exact (0), as writers print whole times without decimals.
pub(super) fn printed_resolution(text: &str) -> f64 {
    if !text.contains(['.', 'e', 'E']) {
        return 0.0;
    }
    let (mantissa, exponent) = match text.find(['e', 'E']) {
        Some(i) => (&text[..i], text[i + 1..].parse::<i32>().unwrap_or(0)),
        None => (text, 0),
    };
    let decimals = mantissa.find('.').map_or(0, |i| mantissa.len() - i - 1) as i32;
    10f64.powi(exponent - decimals)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fields(line: &str, delim: char) -> Vec<String> {
        split_fields(line, delim)
            .into_iter()
            .map(Cow::into_owned)
            .collect()
    }

    #[test]
    fn quoted_fields_keep_separators_and_doubled_quotes() {
        assert_eq!(
            fields(r#"time, "Acc, top" ,"say ""hi""",S4"#, ','),
            ["time", "Acc, top", r#"say "hi""#, "S4"]
        );
        assert_eq!(fields(r#""0.5";"-1e-3";"#, ';'), ["0.5", "-1e-3", ""]);
        assert_eq!(fields("1, 2 ,3", ','), ["1", "2", "3"]);
        // An unclosed quote runs to the end of the line.
        assert_eq!(fields(r#"a,"b,c"#, ','), ["a", "b,c"]);
        assert_eq!(fields(r#""""#, ','), [""]);
    }

    #[test]
    fn printed_resolution_counts_the_last_digit() {
        assert_eq!(printed_resolution("3"), 0.0);
        assert!((printed_resolution("0.00025") - 1e-5).abs() < 1e-20);
        assert!((printed_resolution("2.5e-4") - 1e-5).abs() < 1e-20);
    }
}
