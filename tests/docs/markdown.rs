//! What the documentation test reads in a Markdown page: fenced blocks with the markers above
//! them, inline code, links and headings' anchors.

use std::path::{Path, PathBuf};

/// A page: `README.md` or `docs/NAME.md`.
pub struct Page {
    /// The path relative to the repository, as messages name it.
    pub name: String,
    pub path: PathBuf,
    pub text: String,
}

impl Page {
    pub fn read(root: &Path, name: &str) -> Page {
        let path = root.join(name);
        let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
        Page {
            name: name.to_owned(),
            path,
            text,
        }
    }

    /// `README.md` and every `docs/*.md`, in that order.
    pub fn all(root: &Path) -> Vec<Page> {
        let mut names: Vec<String> = std::fs::read_dir(root.join("docs"))
            .expect("docs/")
            .map(|e| {
                e.expect("an entry of docs/")
                    .file_name()
                    .to_string_lossy()
                    .into_owned()
            })
            .filter(|n| n.ends_with(".md"))
            .map(|n| format!("docs/{n}"))
            .collect();
        names.sort();
        names.insert(0, "README.md".to_owned());
        if let Some(only) = Page::only() {
            names.retain(|n| only.iter().any(|o| n == o || n.strip_prefix("docs/") == Some(o)));
        }
        names.iter().map(|n| Page::read(root, n)).collect()
    }

    /// The pages `CPMX_DOCS_PAGES` names (comma-separated, `README.md`, `docs/x.md` or `x.md`),
    /// for a quick check of the pages being edited; unset, every page.
    pub fn only() -> Option<Vec<String>> {
        let value = std::env::var("CPMX_DOCS_PAGES").ok()?;
        Some(value.split(',').map(|n| n.trim().to_owned()).collect())
    }

    /// A short name for scratch files: `README`, `docs-benchmark`.
    pub fn stem(&self) -> String {
        self.name.trim_end_matches(".md").replace('/', "-")
    }

    /// Every fenced block.
    pub fn blocks(&self) -> Vec<Block> {
        let lines: Vec<&str> = self.text.lines().collect();
        let mut blocks = Vec::new();
        let mut i = 0;
        while i < lines.len() {
            let Some(info) = lines[i].trim_start().strip_prefix("```") else {
                i += 1;
                continue;
            };
            let start = i;
            let mut end = i + 1;
            while end < lines.len() && !lines[end].trim_start().starts_with("```") {
                end += 1;
            }
            let mut markers = Vec::new();
            let mut j = start;
            while j > 0 {
                let above = lines[j - 1].trim();
                match above.strip_prefix("<!--").and_then(|m| m.strip_suffix("-->")) {
                    Some(marker) => markers.push(marker.trim().to_owned()),
                    None => break,
                }
                j -= 1;
            }
            let mut body = lines[start + 1..end.min(lines.len())].join("\n");
            body.push('\n');
            blocks.push(Block {
                line: start + 1,
                lang: info.trim().to_owned(),
                body,
                markers,
            });
            i = end + 1;
        }
        blocks
    }

    /// The lines outside fenced blocks, with their line numbers.
    pub fn prose(&self) -> Vec<(usize, &str)> {
        let mut fenced = false;
        let mut out = Vec::new();
        for (i, line) in self.text.lines().enumerate() {
            if line.trim_start().starts_with("```") {
                fenced = !fenced;
                continue;
            }
            if !fenced {
                out.push((i + 1, line));
            }
        }
        out
    }

    /// Inline code in the prose, with its line (a span may run over lines of a paragraph;
    /// `\\|`, a bar inside a table cell, is read as `|`).
    pub fn inline_code(&self) -> Vec<(usize, String)> {
        // Paragraphs: runs of prose lines without a blank line or a fence between them.
        let mut paragraphs: Vec<(usize, String)> = Vec::new();
        let mut last = 0;
        for (line, text) in self.prose() {
            match paragraphs.last_mut() {
                Some((_, paragraph)) if line == last + 1 && !text.trim().is_empty() => {
                    paragraph.push('\n');
                    paragraph.push_str(text);
                }
                _ if !text.trim().is_empty() => paragraphs.push((line, text.to_owned())),
                _ => {}
            }
            // A blank line ends the paragraph: the next line is not `last + 1`.
            if !text.trim().is_empty() {
                last = line;
            }
        }
        let mut out = Vec::new();
        for (first, paragraph) in paragraphs {
            let chars: Vec<char> = paragraph.chars().collect();
            let mut i = 0;
            while i < chars.len() {
                if chars[i] != '`' {
                    i += 1;
                    continue;
                }
                let ticks = chars[i..].iter().take_while(|&&c| c == '`').count();
                let open = i + ticks;
                let mut j = open;
                let mut close = None;
                while j < chars.len() {
                    if chars[j] == '`' {
                        let run = chars[j..].iter().take_while(|&&c| c == '`').count();
                        if run == ticks {
                            close = Some(j);
                            break;
                        }
                        j += run;
                    } else {
                        j += 1;
                    }
                }
                let Some(close) = close else { break };
                let code: String = chars[open..close].iter().collect();
                let line = first + chars[..i].iter().filter(|&&c| c == '\n').count();
                let code = code.split_whitespace().collect::<Vec<_>>().join(" ");
                out.push((line, code.replace("\\|", "|")));
                i = close + ticks;
            }
        }
        out
    }

    /// Links to other files or anchors (`[text](target)`), with their line.
    pub fn links(&self) -> Vec<(usize, String)> {
        let mut out = Vec::new();
        for (line, text) in self.prose() {
            let mut rest = text;
            while let Some(at) = rest.find("](") {
                let after = &rest[at + 2..];
                let Some(end) = after.find(')') else { break };
                let target = after[..end].trim();
                let target = target.split_whitespace().next().unwrap_or_default();
                if !target.is_empty() && !target.contains("://") && !target.starts_with("mailto:") {
                    out.push((line, target.to_owned()));
                }
                rest = &after[end..];
            }
        }
        out
    }

    /// The anchors of the page's headings, as GitHub makes them.
    pub fn anchors(&self) -> Vec<String> {
        let mut seen: Vec<String> = Vec::new();
        let mut out = Vec::new();
        for (_, line) in self.prose() {
            let Some(heading) = line.strip_prefix('#') else {
                continue;
            };
            let heading = heading.trim_start_matches('#');
            if !heading.starts_with(' ') {
                continue;
            }
            let slug = slug(heading.trim());
            let count = seen.iter().filter(|s| **s == slug).count();
            out.push(if count == 0 {
                slug.clone()
            } else {
                format!("{slug}-{count}")
            });
            seen.push(slug);
        }
        out
    }
}

/// GitHub's anchor of a heading: lower case, spaces as `-`, punctuation but `-` and `_` left
/// out, inline code's backticks too.
pub fn slug(heading: &str) -> String {
    heading
        .to_lowercase()
        .chars()
        .filter_map(|c| match c {
            ' ' => Some('-'),
            c if c.is_alphanumeric() || c == '-' || c == '_' => Some(c),
            _ => None,
        })
        .collect()
}

/// A fenced block.
pub struct Block {
    /// The line of its opening fence (1-based).
    pub line: usize,
    /// The info string: `yaml`, `sh`, `console`, `python`, or empty.
    pub lang: String,
    pub body: String,
    /// The HTML comments directly above the fence, innermost first, without `<!--` `-->`.
    pub markers: Vec<String>,
}

impl Block {
    /// The text of the marker `KEY: VALUE` (`file`, `base`, `exit`, `not validated`).
    pub fn marker(&self, key: &str) -> Option<&str> {
        self.markers
            .iter()
            .find_map(|m| m.strip_prefix(key).and_then(|v| v.strip_prefix(':')))
            .map(str::trim)
    }

    /// The `not run` markers: `None` for the whole block, `Some(prefix)` for the lines that
    /// start with the prefix (`<!-- not run `scripts/test`: why -->`).
    pub fn not_run(&self) -> Vec<Option<String>> {
        self.markers
            .iter()
            .filter_map(|m| m.strip_prefix("not run"))
            .map(|rest| {
                let rest = rest.trim_start();
                rest.strip_prefix('`')
                    .and_then(|r| r.split_once('`'))
                    .map(|(prefix, _)| prefix.to_owned())
            })
            .collect()
    }

    /// Whether the block is a whole spec (it has the `cpmx: 1` line).
    pub fn is_whole_spec(&self) -> bool {
        self.body.lines().any(|l| l.trim_end() == "cpmx: 1")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn page(text: &str) -> Page {
        Page {
            name: "t.md".into(),
            path: PathBuf::from("t.md"),
            text: text.into(),
        }
    }

    #[test]
    fn blocks_carry_their_markers() {
        let p = page("a\n<!-- not run: long -->\n<!-- exit: 1 -->\n```sh\ncpmx x\n```\n");
        let blocks = p.blocks();
        assert_eq!(blocks.len(), 1);
        assert_eq!(blocks[0].line, 4);
        assert_eq!(blocks[0].body, "cpmx x\n");
        assert_eq!(blocks[0].marker("exit"), Some("1"));
        assert_eq!(blocks[0].not_run(), vec![None]);
    }

    #[test]
    fn anchors_and_inline_code() {
        let p = page("# The paper's `at25` benchmark\n## A, b\n## A, b\nsee `cpmx run X` and ``a ` b``\n");
        assert_eq!(p.anchors(), ["the-papers-at25-benchmark", "a-b", "a-b-1"]);
        let code: Vec<String> = p.inline_code().into_iter().map(|(_, c)| c).collect();
        assert_eq!(code, ["at25", "cpmx run X", "a ` b"]);
    }

    #[test]
    fn inline_code_runs_over_the_lines_of_a_paragraph() {
        let p = page("one `cpmx train\nSPEC --resume` two\n\n| `a \\| b` |\n");
        assert_eq!(
            p.inline_code(),
            [
                (1, "cpmx train SPEC --resume".to_owned()),
                (4, "a | b".to_owned())
            ]
        );
    }
}
