//! The summary as HTML: the run folder's `summary.md` (Table 2, the intervals, the paired
//! comparison and their notes) turned into HTML, so the page and the Markdown file can never
//! say different things. Only the Markdown that `cpmx_report` writes is understood: headings,
//! paragraphs, pipe tables, bullet lists, `**bold**` and `` `code` ``.

use cpmx_report::{Format, Summary, render};

/// The summary tables and their notes.
pub fn summary_tables(summary: &Summary) -> String {
    markdown_to_html(&render(summary, Format::Markdown))
}

/// HTML of the Markdown subset the summary uses (its first `#` heading is left out: the
/// page has its own).
fn markdown_to_html(markdown: &str) -> String {
    let mut out = String::new();
    let mut lines = markdown.lines().peekable();
    while let Some(line) = lines.next() {
        if line.starts_with("# ") || line.trim().is_empty() {
            continue;
        }
        if let Some(heading) = line.strip_prefix("## ") {
            out.push_str(&format!("<h3>{}</h3>\n", inline(heading)));
        } else if let Some(heading) = line.strip_prefix("### ") {
            out.push_str(&format!("<h4>{}</h4>\n", inline(heading)));
        } else if line.starts_with('|') {
            let mut rows = vec![line];
            while let Some(next) = lines.next_if(|l| l.starts_with('|')) {
                rows.push(next);
            }
            out.push_str(&table(&rows));
        } else if let Some(item) = line.strip_prefix("- ") {
            out.push_str("<ul>\n");
            out.push_str(&format!("<li>{}</li>\n", inline(item)));
            while let Some(next) = lines.next_if(|l| l.starts_with("- ")) {
                out.push_str(&format!("<li>{}</li>\n", inline(&next[2..])));
            }
            out.push_str("</ul>\n");
        } else {
            out.push_str(&format!("<p class=\"note\">{}</p>\n", inline(line)));
        }
    }
    out
}

/// A pipe table: header row, alignment row, body rows; in a box that scrolls sideways when
/// the table is wider than the page (a phone).
fn table(rows: &[&str]) -> String {
    let cells = |row: &str| -> Vec<String> {
        let inner = row.trim().trim_start_matches('|').trim_end_matches('|');
        // `\|` inside a cell is an escaped pipe.
        let mut cells = Vec::new();
        let mut current = String::new();
        let mut chars = inner.chars().peekable();
        while let Some(c) = chars.next() {
            match c {
                '\\' if chars.peek() == Some(&'|') => {
                    current.push('|');
                    chars.next();
                }
                '|' => cells.push(std::mem::take(&mut current).trim().to_owned()),
                _ => current.push(c),
            }
        }
        cells.push(current.trim().to_owned());
        cells
    };
    let right: Vec<bool> = rows
        .get(1)
        .map(|r| {
            cells(r)
                .iter()
                .map(|c| c.ends_with(':') && !c.starts_with(':'))
                .collect()
        })
        .unwrap_or_default();
    let mut out = String::from("<div class=\"table-wrap\"><table>\n<thead><tr>");
    for cell in cells(rows[0]) {
        out.push_str(&format!("<th>{}</th>", inline(&cell)));
    }
    out.push_str("</tr></thead>\n<tbody>\n");
    for row in rows.iter().skip(2) {
        out.push_str("<tr>");
        for (i, cell) in cells(row).iter().enumerate() {
            let class = if right.get(i).copied().unwrap_or(false) {
                " class=\"num\""
            } else {
                ""
            };
            out.push_str(&format!("<td{class}>{}</td>", inline(cell)));
        }
        out.push_str("</tr>\n");
    }
    out.push_str("</tbody>\n</table></div>\n");
    out
}

/// Inline Markdown: `**bold**` and `` `code` `` on escaped text.
fn inline(text: &str) -> String {
    let escaped = escape(text);
    let mut out = String::new();
    let (mut bold, mut code) = (false, false);
    let mut rest = escaped.as_str();
    while !rest.is_empty() {
        if !code && rest.starts_with("**") {
            out.push_str(if bold { "</strong>" } else { "<strong>" });
            bold = !bold;
            rest = &rest[2..];
        } else if rest.starts_with('`') {
            out.push_str(if code { "</code>" } else { "<code>" });
            code = !code;
            rest = &rest[1..];
        } else {
            let c = rest.chars().next().unwrap_or(' ');
            out.push(c);
            rest = &rest[c.len_utf8()..];
        }
    }
    if bold {
        out.push_str("</strong>");
    }
    if code {
        out.push_str("</code>");
    }
    out
}

/// Text with HTML's special characters escaped.
pub fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_summary_subset_of_markdown_becomes_html() {
        let md = "# x\n\nSome **bold** and `code` <b>.\n\n| a | b \\| c |\n| :-- | --: |\n| 1 | **2** |\n\n## Notes\n\n- one\n- two\n\n### Detail\n";
        let html = markdown_to_html(md);
        assert_eq!(
            html,
            "<p class=\"note\">Some <strong>bold</strong> and <code>code</code> &lt;b&gt;.</p>\n\
             <div class=\"table-wrap\"><table>\n<thead><tr><th>a</th><th>b | c</th></tr></thead>\n<tbody>\n\
             <tr><td>1</td><td class=\"num\"><strong>2</strong></td></tr>\n</tbody>\n</table></div>\n\
             <h3>Notes</h3>\n<ul>\n<li>one</li>\n<li>two</li>\n</ul>\n<h4>Detail</h4>\n"
        );
    }
}
