//! XML helpers the loaders share: parse errors located where the text breaks off, and the
//! location of a node's start tag.

use roxmltree::Node;

use crate::error::{LineIndex, MapError, SourceLocation};

/// The location of a node's start tag.
pub(crate) fn loc(index: &LineIndex, node: Node) -> SourceLocation {
    index.locate(node.range().start)
}

/// Converts a roxmltree parse error. A text that ends early (a truncated file) is reported
/// at its end, naming the innermost element still open and where it was opened: errors
/// roxmltree places at 1:1 because the stream ended, and errors inside markup that never
/// closes (a file cut after `<` or `</`, which roxmltree calls an unknown or invalid token).
pub(crate) fn xml_error(text: &str, e: &roxmltree::Error) -> MapError {
    let pos = e.pos();
    let at = SourceLocation::from_line_column(text, pos.row, pos.col);
    let ended_early = matches!(
        e,
        roxmltree::Error::UnexpectedEndOfStream | roxmltree::Error::UnclosedRootNode
    ) || breaks_off_after(text, at.offset);
    if !ended_early {
        return MapError::NotXml {
            location: at,
            message: e.to_string(),
        };
    }
    let index = LineIndex::new(text);
    let end = text.trim_end().len();
    let message = match open_elements(text).last() {
        Some((name, start)) => format!(
            "the file ends inside <{name}> (opened at {}); is it truncated?",
            index.locate(*start)
        ),
        None => format!("{e}; is the file truncated?"),
    };
    MapError::NotXml {
        location: index.locate(end),
        message,
    }
}

/// Whether the text from the start of the markup around `offset` to its end is one
/// unfinished piece of markup (no `>` closes it): the file was cut there.
fn breaks_off_after(text: &str, offset: usize) -> bool {
    // The markup character at `offset` itself counts (roxmltree points at a lone `<`).
    let through = text.get(..=offset).or(text.get(..offset)).unwrap_or_default();
    let start = through.rfind(['<', '>']).unwrap_or(offset);
    text.get(start..)
        .is_some_and(|rest| rest.starts_with('<') && !rest.contains('>'))
}

/// The elements still open at the end of `text` (name and byte offset of the start tag),
/// outermost first, by a tolerant scan that skips comments, processing instructions, CDATA
/// and quoted attribute values.
fn open_elements(text: &str) -> Vec<(String, usize)> {
    let bytes = text.as_bytes();
    let mut stack: Vec<(String, usize)> = Vec::new();
    let mut i = 0;
    while let Some(off) = text.get(i..).and_then(|t| t.find('<')) {
        let start = i + off;
        let rest = &text[start..];
        let skip_to = |end: &str| rest.find(end).map(|p| start + p + end.len());
        let next = if rest.starts_with("<!--") {
            skip_to("-->")
        } else if rest.starts_with("<![CDATA[") {
            skip_to("]]>")
        } else if rest.starts_with("<?") || rest.starts_with("<!") {
            skip_to(">")
        } else if let Some(close) = rest.strip_prefix("</") {
            let name: String = close
                .chars()
                .take_while(|c| !c.is_whitespace() && *c != '>')
                .collect();
            if let Some(p) = stack.iter().rposition(|(n, _)| *n == name) {
                stack.truncate(p);
            }
            skip_to(">")
        } else {
            // A start tag: find its end outside quotes.
            let name: String = rest[1..]
                .chars()
                .take_while(|c| !c.is_whitespace() && *c != '>' && *c != '/')
                .collect();
            let mut quote = None;
            let mut end = None;
            for (j, &b) in bytes[start + 1..].iter().enumerate() {
                match (quote, b) {
                    (Some(q), b) if b == q => quote = None,
                    (Some(_), _) => {}
                    (None, b'"' | b'\'') => quote = Some(b),
                    (None, b'>') => {
                        end = Some(start + 1 + j);
                        break;
                    }
                    _ => {}
                }
            }
            match end {
                Some(e) => {
                    if bytes[e - 1] != b'/' && !name.is_empty() {
                        stack.push((name, start));
                    }
                    Some(e + 1)
                }
                None => {
                    if !name.is_empty() {
                        stack.push((name, start));
                    }
                    None
                }
            }
        };
        match next {
            Some(n) if n > i => i = n,
            _ => break,
        }
    }
    stack
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn truncated_text_is_located_at_its_end() {
        let text = "<osm>\n  <node id='1' lat='1' lon='2'/>\n  <way id='2'>\n    <nd ref='1'/>\n    <nd re";
        let Err(e) = roxmltree::Document::parse(text) else {
            panic!("parses")
        };
        let MapError::NotXml { location, message } = xml_error(text, &e) else {
            panic!("not NotXml")
        };
        assert_eq!((location.line, location.column), (5, 11), "{message}");
        assert!(message.contains("<nd> (opened at 5:5)"), "{message}");
        let text = "<osm>\n  <way id='2'>\n    <nd ref='1'/>\n";
        let e = roxmltree::Document::parse(text).expect_err("truncated");
        let MapError::NotXml { location, message } = xml_error(text, &e) else {
            panic!("not NotXml")
        };
        assert_eq!(location.line, 3, "{message}");
        assert!(message.contains("<way> (opened at 2:3)"), "{message}");
    }

    /// Cut right after `<` or `</`: roxmltree sees an unknown or invalid token, and the
    /// diagnostic still says where the file breaks off and which element is open.
    #[test]
    fn text_cut_inside_a_tag_is_reported_as_truncated() {
        for (text, line, column, open) in [
            (
                "<commonRoad>\n  <lanelet id='1'>\n    <x>1</x>\n    <",
                4,
                6,
                "<lanelet> (opened at 2:3)",
            ),
            (
                "<commonRoad>\n  <lanelet id='1'>\n    <x>1</",
                3,
                11,
                "<x> (opened at 3:5)",
            ),
            (
                "<commonRoad>\n  <lanelet id='1'>\n    <x>1</x>\n  </lane",
                4,
                9,
                "<lanelet> (opened at 2:3)",
            ),
        ] {
            let e = roxmltree::Document::parse(text).expect_err("truncated");
            let MapError::NotXml { location, message } = xml_error(text, &e) else {
                panic!("not NotXml")
            };
            assert_eq!(
                (location.line, location.column),
                (line, column),
                "{text:?}: {message}"
            );
            assert!(message.contains(open), "{text:?}: {message}");
        }
        // A broken tag followed by more markup is a syntax error where roxmltree finds it.
        let text = "<commonRoad>\n  <lanelet id='1'>\n    <1x>1</x>\n  </lanelet>\n</commonRoad>\n";
        let e = roxmltree::Document::parse(text).expect_err("invalid");
        let MapError::NotXml { location, message } = xml_error(text, &e) else {
            panic!("not NotXml")
        };
        assert_eq!(location.line, 3, "{message}");
        assert!(!message.contains("truncated"), "{message}");
    }
}
