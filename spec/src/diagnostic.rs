//! Problems found in a spec, and their rendering as miette diagnostics.
//!
//! A `Problem` is what a check produces: a code, a message, a labelled byte span and a help
//! line. `SpecDiagnostic` attaches the spec's text so that miette can show the place with its
//! file, line and column. Only the CLI prints them.

use std::fmt;
use std::sync::Arc;

use miette::{
    Diagnostic, GraphicalReportHandler, GraphicalTheme, LabeledSpan, NamedSource, Severity, SourceSpan,
};

/// A byte range of the spec's text.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ByteSpan {
    pub offset: usize,
    pub len: usize,
}

impl ByteSpan {
    pub fn new(offset: usize, len: usize) -> Self {
        Self { offset, len }
    }
}

/// How bad a problem is: errors stop `validate`, `plan` and `run`; warnings are shown only.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Level {
    Error,
    Warning,
}

/// One problem of a spec.
#[derive(Debug, Clone, PartialEq)]
pub struct Problem {
    /// Stable identifier of the kind of problem, e.g. `cpmx::schema::type`.
    pub code: &'static str,
    pub level: Level,
    pub message: String,
    /// The node the problem is about.
    pub span: ByteSpan,
    /// What the label under the node says.
    pub label: String,
    /// What to do about it.
    pub help: Option<String>,
    /// The name the spec most likely meant where it has an unknown one (the help's "did you
    /// mean"), for tools that read on past the problem.
    pub suggestion: Option<String>,
    /// The JSON pointer of the node the problem is about (in the spec with its presets
    /// expanded), where the check knows it: for tools that read on past the problem.
    pub pointer: Option<String>,
}

impl Problem {
    /// An error at `span`.
    pub fn error(
        code: &'static str,
        message: impl Into<String>,
        span: ByteSpan,
        label: impl Into<String>,
    ) -> Self {
        Self {
            code,
            level: Level::Error,
            message: message.into(),
            span,
            label: label.into(),
            help: None,
            suggestion: None,
            pointer: None,
        }
    }

    /// A warning at `span`.
    pub fn warning(
        code: &'static str,
        message: impl Into<String>,
        span: ByteSpan,
        label: impl Into<String>,
    ) -> Self {
        Self {
            level: Level::Warning,
            ..Self::error(code, message, span, label)
        }
    }

    /// Adds a help line.
    pub fn with_help(mut self, help: impl Into<String>) -> Self {
        self.help = Some(help.into());
        self
    }

    /// Adds the name most likely meant, and the help line "did you mean `name`?".
    pub fn with_suggestion(mut self, name: impl Into<String>) -> Self {
        let name = name.into();
        self.help = Some(format!("did you mean `{name}`?"));
        self.suggestion = Some(name);
        self
    }

    /// Names the node the problem is about (its JSON pointer).
    pub fn at_pointer(mut self, pointer: impl Into<String>) -> Self {
        self.pointer = Some(pointer.into());
        self
    }

    pub(crate) fn yaml_syntax(message: String, span: ByteSpan) -> Self {
        Self::error(
            "cpmx::yaml::syntax",
            format!("the spec is not valid YAML: {message}"),
            span,
            "here",
        )
        .with_help("YAML is indentation-sensitive; check the line above the marked place too")
    }

    pub(crate) fn empty_document() -> Self {
        Self::error(
            "cpmx::yaml::empty",
            "the spec is empty",
            ByteSpan::new(0, 0),
            "no content",
        )
        .with_help("start from `cpmx run experiments/quickstart.yaml` or an example in `examples/`")
    }

    pub(crate) fn number_out_of_range(span: ByteSpan) -> Self {
        Self::error(
            "cpmx::yaml::number",
            "this integer does not fit in 64 bits",
            span,
            "too large",
        )
    }

    pub(crate) fn non_finite_number(span: ByteSpan) -> Self {
        Self::error("cpmx::yaml::number", "numbers must be finite", span, "not finite")
            .with_help("`.inf` and `.nan` cannot be used as parameters")
    }

    pub(crate) fn non_scalar_key(span: ByteSpan) -> Self {
        Self::error(
            "cpmx::yaml::key",
            "keys must be plain names",
            span,
            "a collection used as a key",
        )
    }

    pub(crate) fn duplicate_key(name: &str, span: ByteSpan) -> Self {
        Self::error(
            "cpmx::yaml::duplicate-key",
            format!("key `{name}` appears twice"),
            span,
            "second occurrence",
        )
        .with_help("a mapping can hold each key once; remove or rename one of them")
    }
}

/// A problem together with the text it is about, ready for miette.
#[derive(Debug, Clone)]
pub struct SpecDiagnostic {
    pub problem: Problem,
    pub source: Arc<NamedSource<String>>,
    /// 1-based line of the span's start.
    pub line: usize,
    /// 1-based column (in characters) of the span's start.
    pub column: usize,
}

impl SpecDiagnostic {
    pub fn new(problem: Problem, source: Arc<NamedSource<String>>) -> Self {
        let text = source.inner();
        let offset = problem.span.offset.min(text.len());
        let before = &text[..offset];
        let line = before.matches('\n').count() + 1;
        let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
        Self {
            problem,
            source,
            line,
            column,
        }
    }

    pub fn is_error(&self) -> bool {
        self.problem.level == Level::Error
    }
}

impl fmt::Display for SpecDiagnostic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.problem.message)
    }
}

impl std::error::Error for SpecDiagnostic {}

impl Diagnostic for SpecDiagnostic {
    fn code<'a>(&'a self) -> Option<Box<dyn fmt::Display + 'a>> {
        Some(Box::new(self.problem.code))
    }

    fn severity(&self) -> Option<Severity> {
        Some(match self.problem.level {
            Level::Error => Severity::Error,
            Level::Warning => Severity::Warning,
        })
    }

    fn help<'a>(&'a self) -> Option<Box<dyn fmt::Display + 'a>> {
        self.problem
            .help
            .as_ref()
            .map(|h| Box::new(h) as Box<dyn fmt::Display>)
    }

    fn source_code(&self) -> Option<&dyn miette::SourceCode> {
        Some(self.source.as_ref())
    }

    fn labels(&self) -> Option<Box<dyn Iterator<Item = LabeledSpan> + '_>> {
        let span = SourceSpan::new(self.problem.span.offset.into(), self.problem.span.len);
        Some(Box::new(std::iter::once(LabeledSpan::new_with_span(
            Some(self.problem.label.clone()),
            span,
        ))))
    }
}

/// Renders diagnostics as text: plain (no colour, fixed width) for files, tests and pipes;
/// with colour for a terminal.
pub fn render(diagnostics: &[SpecDiagnostic], colour: bool) -> String {
    let theme = if colour {
        GraphicalTheme::unicode()
    } else {
        GraphicalTheme::unicode_nocolor()
    };
    let handler = GraphicalReportHandler::new_themed(theme)
        .with_width(100)
        .with_links(false);
    let mut out = String::new();
    for d in diagnostics {
        // Writing into a String cannot fail.
        let _ = handler.render_report(&mut out, d);
    }
    out
}
