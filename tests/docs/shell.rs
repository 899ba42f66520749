//! The commands of a shell block: lines joined at `\`, comments left out, `cargo run
//! --release --` read as the `cpmx` it builds, and in a console block the output that follows
//! a `$ ` line.

/// One command of a block, with the output a console block shows for it.
#[derive(Debug, PartialEq)]
pub struct Command {
    /// The line in the page where it starts.
    pub line: usize,
    /// The command as bash runs it.
    pub text: String,
    /// The output shown below it (console blocks); `...` stands for any lines.
    pub output: Vec<String>,
}

impl Command {
    /// The words of the command before its first `|`, `;`, `&&` or redirection, without
    /// leading variable assignments and wrappers (`time`, `taskset -c 0`).
    pub fn program(&self) -> Vec<&str> {
        let mut words: Vec<&str> = self
            .text
            .split_whitespace()
            .take_while(|w| !matches!(*w, "|" | ";" | "&&" | "||" | ">" | ">>" | "&"))
            .collect();
        loop {
            match words.first() {
                Some(w) if is_assignment(w) || *w == "time" || *w == "nice" => {
                    words.remove(0);
                }
                Some(&"taskset") => {
                    words.drain(..3.min(words.len()));
                }
                _ => break,
            }
        }
        words
    }

    /// Whether the command runs cpmx somewhere.
    pub fn runs_cpmx(&self) -> bool {
        self.text.split_whitespace().any(|w| w == "cpmx")
    }
}

fn is_assignment(word: &str) -> bool {
    word.split_once('=')
        .is_some_and(|(name, _)| !name.is_empty() && name.chars().all(|c| c.is_ascii_uppercase() || c == '_'))
}

/// The text before a `#` comment that is not inside quotes.
fn strip_comment(line: &str) -> &str {
    let mut quote = None;
    let mut previous = ' ';
    for (i, c) in line.char_indices() {
        match (quote, c) {
            (None, '\'' | '"') => quote = Some(c),
            (Some(q), c) if c == q => quote = None,
            (None, '#') if previous.is_whitespace() => return line[..i].trim_end(),
            _ => {}
        }
        previous = c;
    }
    line.trim_end()
}

/// `cargo run --release -- ARGS` (and `cargo run -- ARGS`) as `cpmx ARGS`.
fn as_cpmx(text: &str) -> String {
    text.replace("cargo run --release -- ", "cpmx ")
        .replace("cargo run -- ", "cpmx ")
}

/// The commands of a block starting at page line `first_line` (the line after the fence).
pub fn commands(body: &str, first_line: usize, console: bool) -> Vec<Command> {
    let mut out: Vec<Command> = Vec::new();
    let mut pending: Option<Command> = None;
    for (i, raw) in body.lines().enumerate() {
        let line = first_line + i;
        if let Some(command) = pending.as_mut() {
            let text = strip_comment(raw);
            let (text, more) = match text.strip_suffix('\\') {
                Some(t) => (t, true),
                None => (text, false),
            };
            command.text.push(' ');
            command.text.push_str(text.trim());
            if !more {
                let done = pending.take().expect("a pending command");
                out.push(Command {
                    text: as_cpmx(done.text.trim()),
                    ..done
                });
            }
            continue;
        }
        let text = if console {
            match raw.strip_prefix("$ ") {
                Some(command) => command,
                None => {
                    if let Some(last) = out.last_mut()
                        && !(raw.trim().is_empty() && last.output.is_empty())
                    {
                        last.output.push(raw.trim_end().to_owned());
                    }
                    continue;
                }
            }
        } else {
            raw
        };
        let text = strip_comment(text);
        if text.trim().is_empty() {
            continue;
        }
        match text.strip_suffix('\\') {
            Some(start) => {
                pending = Some(Command {
                    line,
                    text: start.trim().to_owned(),
                    output: Vec::new(),
                })
            }
            None => out.push(Command {
                line,
                text: as_cpmx(text.trim()),
                output: Vec::new(),
            }),
        }
    }
    if let Some(done) = pending {
        out.push(Command {
            text: as_cpmx(done.text.trim()),
            ..done
        });
    }
    for command in &mut out {
        while command.output.last().is_some_and(|l| l.trim().is_empty()) {
            command.output.pop();
        }
    }
    out
}

/// Whether `actual` shows `expected`, line by line (trailing spaces aside); an expected `...`
/// line stands for any number of lines.
pub fn output_matches(expected: &[String], actual: &str) -> bool {
    let actual: Vec<&str> = actual.lines().map(str::trim_end).collect();
    fn matches(expected: &[String], actual: &[&str]) -> bool {
        match expected.split_first() {
            None => actual.is_empty(),
            Some((first, rest)) if first.trim() == "..." => {
                (0..=actual.len()).any(|skip| matches(rest, &actual[skip..]))
            }
            Some((first, rest)) => {
                actual.first().is_some_and(|a| *a == first.trim_end()) && matches(rest, &actual[1..])
            }
        }
    }
    matches(expected, &actual)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_comments_and_continuations() {
        let body = "cargo run --release -- run a.yaml   # the main job\n\
                    CPMX_DATA=x cpmx train b.yaml \\\n    --resume   # continue\n\n# a comment\n";
        let commands = commands(body, 10, false);
        assert_eq!(commands.len(), 2);
        assert_eq!(commands[0].text, "cpmx run a.yaml");
        assert_eq!(commands[0].line, 10);
        assert_eq!(commands[1].text, "CPMX_DATA=x cpmx train b.yaml --resume");
        assert_eq!(commands[1].line, 11);
        assert_eq!(commands[1].program(), ["cpmx", "train", "b.yaml", "--resume"]);
    }

    #[test]
    fn console_output_and_wildcards() {
        let body = "$ cpmx validate a.yaml\nok: 3 runs\n...\n\n$ time taskset -c 0 cpmx run a.yaml\n";
        let commands = commands(body, 1, true);
        assert_eq!(commands[0].output, ["ok: 3 runs", "..."]);
        assert_eq!(commands[1].program()[0], "cpmx");
        assert!(output_matches(&commands[0].output, "ok: 3 runs\nmore\nlines\n"));
        assert!(!output_matches(&commands[0].output, "ok: 4 runs\n"));
        assert!(output_matches(&["...".to_owned()], ""));
    }

    #[test]
    fn quoted_hashes_stay() {
        assert_eq!(strip_comment("printf 'a # b' > x  # why"), "printf 'a # b' > x");
    }
}
