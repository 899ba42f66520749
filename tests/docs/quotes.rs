//! Figures a page quotes from what its commands wrote: a table below
//! `<!-- figures: FILE [FILE...] -->` quotes only numbers that those files hold (files the
//! page's commands wrote in its scratch copy, e.g. `out/at25/summary.md`, or SigmaRL's
//! reference data as `../shared/reference/...`). Every number with a decimal point in the
//! table must appear in one of them as printed (`−` read as `-`, a leading `+` dropped), so a
//! quoted figure that no longer matches its command fails the test.

use std::path::Path;

use crate::markdown::Page;

/// A table that quotes figures, and the files it quotes.
pub struct Quote {
    /// The marker's line (1-based).
    pub line: usize,
    pub files: Vec<String>,
    /// The table's lines with their line numbers.
    pub rows: Vec<(usize, String)>,
}

/// The quoting tables of a page: a `figures:` marker, then (after blank lines at most) a table.
pub fn quotes(page: &Page) -> Vec<Quote> {
    let prose = page.prose();
    let mut out = Vec::new();
    for (i, (line, text)) in prose.iter().enumerate() {
        let Some(files) = text
            .trim()
            .strip_prefix("<!-- figures:")
            .and_then(|m| m.strip_suffix("-->"))
        else {
            continue;
        };
        let rows: Vec<(usize, String)> = prose[i + 1..]
            .iter()
            .skip_while(|(_, t)| t.trim().is_empty())
            .take_while(|(_, t)| t.trim_start().starts_with('|'))
            .map(|(l, t)| (*l, (*t).to_owned()))
            .collect();
        out.push(Quote {
            line: *line,
            files: files.split_whitespace().map(str::to_owned).collect(),
            rows,
        });
    }
    out
}

/// The decimal numbers of `text` as a file would print them: `−0.38` as `-0.38`, `+2.70` as
/// `2.70`.
pub fn numbers(text: &str) -> Vec<String> {
    let text = text.replace('−', "-");
    let bytes = text.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        let starts = bytes[i].is_ascii_digit() && (i == 0 || !is_number_byte(bytes[i - 1]));
        if !starts {
            i += 1;
            continue;
        }
        let mut end = i;
        while end < bytes.len() && (bytes[end].is_ascii_digit() || bytes[end] == b'.') {
            end += 1;
        }
        let token = text[i..end].trim_end_matches('.');
        let negative = i > 0 && bytes[i - 1] == b'-';
        if token.contains('.') {
            out.push(if negative {
                format!("-{token}")
            } else {
                token.to_owned()
            });
        }
        i = end;
    }
    out
}

fn is_number_byte(b: u8) -> bool {
    b.is_ascii_digit() || b == b'.' || b.is_ascii_alphabetic() || b == b'_'
}

/// Whether `number` stands in `text` as a number of its own (not a part of a longer one).
fn holds(text: &str, number: &str) -> bool {
    let bytes = text.as_bytes();
    text.match_indices(number).any(|(at, _)| {
        let before = at.checked_sub(1).map(|i| bytes[i]);
        let after = bytes.get(at + number.len()).copied();
        let digit_or_point = |b: Option<u8>| b.is_some_and(|b| b.is_ascii_digit() || b == b'.');
        // `0.38` is not `-0.38`'s: a sign before a positive quote is another number.
        let signed_other = before == Some(b'-') && !number.starts_with('-');
        !(digit_or_point(before) || signed_other || digit_or_point(after))
    })
}

/// What is wrong with a page's quotes after its commands ran in `repo` (the scratch copy).
pub fn check(page: &Page, repo: &Path) -> Vec<String> {
    let mut failures = Vec::new();
    for quote in quotes(page) {
        let at = format!("{}:{}", page.name, quote.line);
        if quote.rows.is_empty() {
            failures.push(format!("{at}: a `figures:` marker without a table below it"));
            continue;
        }
        let mut texts = String::new();
        for file in &quote.files {
            match std::fs::read_to_string(repo.join(file)) {
                Ok(text) => {
                    texts.push_str(&text.replace('−', "-"));
                    texts.push('\n');
                }
                Err(e) => failures.push(format!("{at}: `{file}`, which the table quotes: {e}")),
            }
        }
        for (line, row) in &quote.rows {
            for number in numbers(row) {
                if !holds(&texts, &number) {
                    failures.push(format!(
                        "{}:{line}: {number} is in none of {} (the figure no longer matches its command)",
                        page.name,
                        quote.files.join(", ")
                    ));
                }
            }
        }
    }
    failures
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_as_files_print_them() {
        assert_eq!(
            numbers("| twin | −0.38 / +2.70 | 0.74 ± 1.82 (0.00) | 27 | [0.02, 1.46] | v2 1.5.0 |"),
            ["-0.38", "2.70", "0.74", "1.82", "0.00", "0.02", "1.46", "1.5.0"]
        );
    }

    #[test]
    fn a_quote_is_a_whole_number_of_the_file() {
        let text = "| sim | 0.74 ± 1.82 | -0.38 | 87.06 |";
        assert!(holds(text, "0.74") && holds(text, "-0.38") && holds(text, "87.06"));
        assert!(!holds(text, "0.38"), "a part of -0.38");
        assert!(!holds(text, "7.06") && !holds(text, "87.0"));
    }
}
