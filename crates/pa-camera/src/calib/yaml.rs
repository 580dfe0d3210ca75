//! A minimal YAML-subset parser: the subset OpenCV's `FileStorage` writes (see the parent
//! module), bounded by [`MAX_NESTING`] and [`MAX_NODES`].

use super::{CalibError, MAX_NESTING, MAX_NODES};

#[derive(Debug, Clone)]
pub(super) struct Node {
    pub(super) line: usize,
    pub(super) value: Value,
}

#[derive(Debug, Clone)]
pub(super) enum Value {
    Scalar(String),
    Seq(Vec<Node>),
    Map(Vec<(String, Node)>),
}

impl Node {
    pub(super) fn get(&self, key: &str) -> Option<&Node> {
        match &self.value {
            Value::Map(entries) => entries.iter().find(|(k, _)| k == key).map(|(_, v)| v),
            _ => None,
        }
    }
}

struct Line<'a> {
    number: usize,
    indent: usize,
    text: &'a str,
}

/// Removes a `#` comment (outside quotes).
fn strip_comment(s: &str) -> &str {
    let mut in_single = false;
    let mut in_double = false;
    let mut prev_space = true;
    for (i, c) in s.char_indices() {
        match c {
            '\'' if !in_double => in_single = !in_single,
            '"' if !in_single => in_double = !in_double,
            '#' if !in_single && !in_double && prev_space => return &s[..i],
            _ => {}
        }
        prev_space = c.is_whitespace() || c == ',' || c == '[' || c == '{';
    }
    s
}

pub(super) fn parse_yaml(text: &str, file: &str) -> Result<Node, CalibError> {
    let mut lines = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let raw = raw.trim_end_matches('\r');
        let t = raw.trim_start();
        if t.starts_with('%') || t == "---" || t == "..." || t.starts_with("--- ") {
            continue;
        }
        let no_comment = strip_comment(raw).trim_end();
        if no_comment.trim().is_empty() {
            continue;
        }
        if raw.starts_with('\t') {
            return Err(CalibError::Syntax {
                file: file.into(),
                line: i + 1,
                message: "tab indentation is not allowed in YAML".into(),
            });
        }
        let indent = no_comment.len() - no_comment.trim_start().len();
        if lines.len() >= MAX_NODES {
            return Err(CalibError::Syntax {
                file: file.into(),
                line: i + 1,
                message: format!("more than {MAX_NODES} lines with values"),
            });
        }
        lines.push(Line {
            number: i + 1,
            indent,
            text: no_comment.trim_start(),
        });
    }
    let mut p = Parser {
        lines,
        pos: 0,
        file,
        depth: 0,
        nodes: 0,
    };
    if p.lines.is_empty() {
        return Ok(Node {
            line: 1,
            value: Value::Map(Vec::new()),
        });
    }
    let indent = p.lines[0].indent;
    let node = p.block(indent)?;
    if p.pos < p.lines.len() {
        return Err(p.err(p.lines[p.pos].number, "unexpected indentation"));
    }
    Ok(node)
}

/// A recursive-descent parser over the lines. Recursion (blocks nested by indentation, flow
/// collections nested by brackets) is bounded by [`MAX_NESTING`] and the values made by
/// [`MAX_NODES`], so no input overflows the stack or amplifies into gigabytes.
struct Parser<'a> {
    lines: Vec<Line<'a>>,
    pos: usize,
    file: &'a str,
    /// Blocks and flow collections open now.
    depth: usize,
    /// Values made so far.
    nodes: usize,
}

impl<'a> Parser<'a> {
    fn err(&self, line: usize, message: impl Into<String>) -> CalibError {
        CalibError::Syntax {
            file: self.file.into(),
            line,
            message: message.into(),
        }
    }

    /// Enters a block or flow collection opened on `line`; pair with [`Parser::leave`].
    fn enter(&mut self, line: usize) -> Result<(), CalibError> {
        if self.depth >= MAX_NESTING {
            return Err(self.err(line, format!("nested deeper than {MAX_NESTING} levels")));
        }
        self.depth += 1;
        Ok(())
    }

    fn leave(&mut self) {
        self.depth -= 1;
    }

    /// Counts a new value made on `line`.
    fn count(&mut self, line: usize) -> Result<(), CalibError> {
        self.nodes += 1;
        if self.nodes > MAX_NODES {
            return Err(self.err(line, format!("more than {MAX_NODES} values")));
        }
        Ok(())
    }

    /// Parses a block (mapping or sequence) whose lines have exactly `indent`.
    fn block(&mut self, indent: usize) -> Result<Node, CalibError> {
        let line = self.lines[self.pos].number;
        self.enter(line)?;
        let node = self.block_inner(indent);
        self.leave();
        node
    }

    fn block_inner(&mut self, indent: usize) -> Result<Node, CalibError> {
        self.count(self.lines[self.pos].number)?;
        let first = &self.lines[self.pos];
        let line = first.number;
        if first.text.starts_with("- ") || first.text == "-" {
            let mut items = Vec::new();
            while self.pos < self.lines.len() && self.lines[self.pos].indent == indent {
                let l = &self.lines[self.pos];
                let Some(rest) = l.text.strip_prefix('-') else {
                    return Err(self.err(l.number, "expected `- ` sequence item"));
                };
                let rest = rest.trim();
                let number = l.number;
                self.pos += 1;
                if rest.is_empty() {
                    items.push(self.nested(indent, number)?);
                } else {
                    items.push(self.inline_value(rest, number)?);
                }
            }
            return Ok(Node {
                line,
                value: Value::Seq(items),
            });
        }
        let mut entries = Vec::new();
        while self.pos < self.lines.len() && self.lines[self.pos].indent == indent {
            let l = &self.lines[self.pos];
            let number = l.number;
            // The line is not repeated: the file may not be ours.
            let (key, rest) = split_key(l.text)
                .ok_or_else(|| self.err(number, "expected `key: value` (a colon and a space)"))?;
            self.pos += 1;
            let mut rest = rest.trim();
            // Tags such as `!!opencv-matrix` or `!<tag:yaml.org,2002:opencv-matrix>`.
            if rest.starts_with('!') {
                rest = rest
                    .split_once(char::is_whitespace)
                    .map(|(_, r)| r.trim())
                    .unwrap_or("");
            }
            let value = if rest.is_empty() {
                self.nested(indent, number)?
            } else {
                self.inline_value(rest, number)?
            };
            entries.push((key, value));
        }
        Ok(Node {
            line,
            value: Value::Map(entries),
        })
    }

    /// The block nested under a key at `indent`, or an empty scalar.
    fn nested(&mut self, indent: usize, line: usize) -> Result<Node, CalibError> {
        if self.pos < self.lines.len() && self.lines[self.pos].indent > indent {
            let ind = self.lines[self.pos].indent;
            self.block(ind)
        } else {
            self.count(line)?;
            Ok(Node {
                line,
                value: Value::Scalar(String::new()),
            })
        }
    }

    /// A value that starts on the key's line; flow collections may continue on later lines.
    fn inline_value(&mut self, rest: &str, line: usize) -> Result<Node, CalibError> {
        if rest.starts_with('[') || rest.starts_with('{') {
            let mut text = rest.to_string();
            // Scanned once, piece by piece: rescanning the whole text for each added line
            // would be quadratic in the file's size.
            let mut balance = FlowBalance::default();
            balance.feed(rest);
            while !balance.closed() {
                if self.pos >= self.lines.len() {
                    return Err(self.err(line, "unterminated flow collection (missing `]` or `}`)"));
                }
                let next = self.lines[self.pos].text;
                text.push(' ');
                text.push_str(next);
                balance.feed(" ");
                balance.feed(next);
                self.pos += 1;
            }
            let chars: Vec<char> = text.chars().collect();
            let mut i = 0;
            let node = self.flow(&chars, &mut i, line)?;
            skip_ws(&chars, &mut i);
            if i < chars.len() {
                return Err(self.err(line, "unexpected text after flow collection"));
            }
            Ok(node)
        } else {
            self.count(line)?;
            Ok(Node {
                line,
                value: Value::Scalar(unquote(rest)),
            })
        }
    }

    /// A flow value at `c[*i]`: a sequence, a mapping or a scalar.
    fn flow(&mut self, c: &[char], i: &mut usize, line: usize) -> Result<Node, CalibError> {
        skip_ws(c, i);
        match c.get(*i) {
            Some('[' | '{') => {
                self.enter(line)?;
                let node = self.flow_collection(c, i, line);
                self.leave();
                node
            }
            Some(']' | '}') => {
                Err(self.err(line, "a flow collection closes where a value was expected"))
            }
            Some(_) => {
                self.count(line)?;
                Ok(Node {
                    line,
                    value: Value::Scalar(self.flow_scalar(c, i, false)),
                })
            }
            None => Err(self.err(line, "missing value")),
        }
    }

    /// The sequence or mapping opening at `c[*i]`.
    fn flow_collection(
        &mut self,
        c: &[char],
        i: &mut usize,
        line: usize,
    ) -> Result<Node, CalibError> {
        self.count(line)?;
        let open = c[*i];
        *i += 1;
        if open == '[' {
            let mut items = Vec::new();
            loop {
                skip_ws(c, i);
                match c.get(*i) {
                    Some(']') => {
                        *i += 1;
                        break;
                    }
                    Some(',') => {
                        *i += 1;
                    }
                    Some('}') => return Err(self.err(line, "`}` closes a `[` sequence")),
                    Some(_) => items.push(self.flow(c, i, line)?),
                    None => return Err(self.err(line, "missing `]`")),
                }
            }
            return Ok(Node {
                line,
                value: Value::Seq(items),
            });
        }
        let mut entries = Vec::new();
        loop {
            skip_ws(c, i);
            match c.get(*i) {
                Some('}') => {
                    *i += 1;
                    break;
                }
                Some(',') => {
                    *i += 1;
                }
                Some(']') => return Err(self.err(line, "`]` closes a `{` mapping")),
                Some(_) => {
                    let key = self.flow_scalar(c, i, true);
                    skip_ws(c, i);
                    if c.get(*i) != Some(&':') {
                        return Err(self.err(line, "expected `:` in flow mapping"));
                    }
                    *i += 1;
                    skip_ws(c, i);
                    if c.get(*i) == Some(&'!') {
                        while *i < c.len() && !c[*i].is_whitespace() {
                            *i += 1;
                        }
                    }
                    // An empty value (`{a: }`, `{a: ,b: 1}`) is an empty scalar.
                    let v = match c.get(*i) {
                        Some('}' | ',') => {
                            self.count(line)?;
                            Node {
                                line,
                                value: Value::Scalar(String::new()),
                            }
                        }
                        _ => self.flow(c, i, line)?,
                    };
                    entries.push((key, v));
                }
                None => return Err(self.err(line, "missing `}`")),
            }
        }
        Ok(Node {
            line,
            value: Value::Map(entries),
        })
    }

    fn flow_scalar(&self, c: &[char], i: &mut usize, is_key: bool) -> String {
        skip_ws(c, i);
        if let Some(&q) = c.get(*i).filter(|q| **q == '"' || **q == '\'') {
            *i += 1;
            let mut s = String::new();
            while *i < c.len() && c[*i] != q {
                s.push(c[*i]);
                *i += 1;
            }
            *i += 1;
            return s;
        }
        let mut s = String::new();
        while *i < c.len() {
            let ch = c[*i];
            if ch == ',' || ch == ']' || ch == '}' || (is_key && ch == ':') {
                break;
            }
            s.push(ch);
            *i += 1;
        }
        s.trim().to_string()
    }
}

fn skip_ws(c: &[char], i: &mut usize) {
    while *i < c.len() && c[*i].is_whitespace() {
        *i += 1;
    }
}

/// Whether the brackets of a flow collection, fed piece by piece, are closed (quotes
/// respected).
#[derive(Default)]
struct FlowBalance {
    depth: i64,
    quote: Option<char>,
}

impl FlowBalance {
    fn feed(&mut self, s: &str) {
        for ch in s.chars() {
            match self.quote {
                Some(q) if ch == q => self.quote = None,
                Some(_) => {}
                None => match ch {
                    '"' | '\'' => self.quote = Some(ch),
                    '[' | '{' => self.depth += 1,
                    ']' | '}' => self.depth -= 1,
                    _ => {}
                },
            }
        }
    }

    fn closed(&self) -> bool {
        self.depth <= 0
    }
}

/// Splits `key: rest` (the colon must be followed by whitespace or end the line).
fn split_key(text: &str) -> Option<(String, &str)> {
    let (key, rest) = if let Some(q) = text.chars().next().filter(|c| *c == '"' || *c == '\'') {
        let end = text[1..].find(q)? + 1;
        let key = text[1..end].to_string();
        let after = text[end + 1..].trim_start();
        (key, after.strip_prefix(':')?)
    } else {
        let mut idx = None;
        for (i, ch) in text.char_indices() {
            if ch == ':' {
                let next = text[i + 1..].chars().next();
                if next.is_none() || next.is_some_and(char::is_whitespace) {
                    idx = Some(i);
                    break;
                }
            }
        }
        let i = idx?;
        (text[..i].trim().to_string(), &text[i + 1..])
    };
    if key.is_empty() {
        return None;
    }
    Some((key, rest))
}

fn unquote(s: &str) -> String {
    let t = s.trim();
    if t.len() >= 2
        && ((t.starts_with('"') && t.ends_with('"')) || (t.starts_with('\'') && t.ends_with('\'')))
    {
        t[1..t.len() - 1].to_string()
    } else {
        t.to_string()
    }
}
