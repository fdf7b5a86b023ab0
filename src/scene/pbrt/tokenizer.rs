//! pbrt-v4's lexical level: bare words and numbers, quoted strings, `[`, `]`, and `#` comments
//! to the end of the line. Tokens borrow the file's text; each carries its line.

use crate::files::snippet;
use std::borrow::Cow;

/// The longest bare token: pbrt's directive names, numbers and bools are far shorter, so a
/// longer one is a damaged or hostile file, refused before any message quotes it in full.
pub const MAX_BARE: usize = 256;

/// The longest quoted string: names and types are short, and scene files name their textures
/// and meshes by short relative paths. Kept low enough that a message quoting a whole string
/// and a bare word stays under 2,000 bytes.
pub const MAX_STRING: usize = 1024;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// A bare token: a directive name, a number, or `true`/`false`.
    Bare,
    /// A quoted string; `text` is between the quotes, escapes not yet resolved.
    Str,
    Open,
    Close,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Token<'a> {
    pub kind: Kind,
    pub text: &'a str,
    pub line: u32,
}

impl Token<'_> {
    /// The string's value with pbrt's escapes (`\n`, `\t`, `\\`, `\"`, ...) resolved.
    pub fn unescaped(&self) -> Cow<'_, str> {
        if !self.text.contains('\\') {
            return Cow::Borrowed(self.text);
        }
        let mut out = String::with_capacity(self.text.len());
        let mut chars = self.text.chars();
        while let Some(c) = chars.next() {
            if c != '\\' {
                out.push(c);
                continue;
            }
            match chars.next() {
                Some('n') => out.push('\n'),
                Some('t') => out.push('\t'),
                Some('r') => out.push('\r'),
                Some('b') => out.push('\u{8}'),
                Some('f') => out.push('\u{c}'),
                Some(other) => out.push(other),
                None => {}
            }
        }
        Cow::Owned(out)
    }

    /// Whether a bare token reads as a number (pbrt's rule: it starts like one).
    pub fn is_number(&self) -> bool {
        self.kind == Kind::Bare
            && matches!(self.text.as_bytes()[0], b'0'..=b'9' | b'-' | b'+' | b'.')
    }
}

/// A lexical error and the line it is on.
#[derive(Clone, Debug, PartialEq)]
pub struct LexError {
    pub line: u32,
    pub message: String,
}

pub struct Tokenizer<'a> {
    src: &'a str,
    pos: usize,
    line: u32,
    peeked: Option<Token<'a>>,
}

impl<'a> Tokenizer<'a> {
    pub fn new(src: &'a str) -> Self {
        Tokenizer {
            src,
            pos: 0,
            line: 1,
            peeked: None,
        }
    }

    /// The line the tokenizer has reached (for errors at the end of the file).
    pub fn line(&self) -> u32 {
        self.peeked.map_or(self.line, |t| t.line)
    }

    pub fn peek(&mut self) -> Result<Option<Token<'a>>, LexError> {
        if self.peeked.is_none() {
            self.peeked = self.scan()?;
        }
        Ok(self.peeked)
    }

    #[allow(clippy::should_implement_trait)]
    pub fn next(&mut self) -> Result<Option<Token<'a>>, LexError> {
        match self.peeked.take() {
            Some(t) => Ok(Some(t)),
            None => self.scan(),
        }
    }

    fn scan(&mut self) -> Result<Option<Token<'a>>, LexError> {
        let bytes = self.src.as_bytes();
        loop {
            let Some(&c) = bytes.get(self.pos) else {
                return Ok(None);
            };
            match c {
                b'\n' => {
                    self.line += 1;
                    self.pos += 1;
                }
                b' ' | b'\t' | b'\r' => self.pos += 1,
                b'#' => {
                    while self.pos < bytes.len() && bytes[self.pos] != b'\n' {
                        self.pos += 1;
                    }
                }
                b'[' | b']' => {
                    let t = Token {
                        kind: if c == b'[' { Kind::Open } else { Kind::Close },
                        text: &self.src[self.pos..self.pos + 1],
                        line: self.line,
                    };
                    self.pos += 1;
                    return Ok(Some(t));
                }
                b'"' => {
                    let start = self.pos + 1;
                    let mut i = start;
                    loop {
                        match bytes.get(i) {
                            None | Some(b'\n') => {
                                return Err(LexError {
                                    line: self.line,
                                    message: "unterminated string".into(),
                                })
                            }
                            Some(b'"') => break,
                            Some(b'\\') => i += 2,
                            Some(_) => i += 1,
                        }
                    }
                    self.pos = i + 1;
                    let text = &self.src[start..i];
                    if text.len() > MAX_STRING {
                        return Err(self.too_long("a quoted string", text, MAX_STRING));
                    }
                    return Ok(Some(Token {
                        kind: Kind::Str,
                        text,
                        line: self.line,
                    }));
                }
                _ => {
                    let start = self.pos;
                    while self.pos < bytes.len()
                        && !matches!(
                            bytes[self.pos],
                            b' ' | b'\t' | b'\r' | b'\n' | b'"' | b'[' | b']' | b'#'
                        )
                    {
                        self.pos += 1;
                    }
                    let text = &self.src[start..self.pos];
                    if text.len() > MAX_BARE {
                        return Err(self.too_long("a bare word", text, MAX_BARE));
                    }
                    return Ok(Some(Token {
                        kind: Kind::Bare,
                        text,
                        line: self.line,
                    }));
                }
            }
        }
    }
}

impl Tokenizer<'_> {
    fn too_long(&self, what: &str, text: &str, max: usize) -> LexError {
        LexError {
            line: self.line,
            message: format!(
                "{what} longer than the {max} bytes a pbrt file may use: '{}'",
                snippet(text)
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn all(src: &str) -> Result<Vec<(Kind, String, u32)>, LexError> {
        let mut t = Tokenizer::new(src);
        let mut out = Vec::new();
        while let Some(tok) = t.next()? {
            out.push((tok.kind, tok.unescaped().into_owned(), tok.line));
        }
        Ok(out)
    }

    #[test]
    fn tokens_lines_and_comments() {
        let toks = all("Shape \"sphere\" # a comment [ ]\n  \"float radius\" [1.5]\n").unwrap();
        assert_eq!(
            toks,
            vec![
                (Kind::Bare, "Shape".into(), 1),
                (Kind::Str, "sphere".into(), 1),
                (Kind::Str, "float radius".into(), 2),
                (Kind::Open, "[".into(), 2),
                (Kind::Bare, "1.5".into(), 2),
                (Kind::Close, "]".into(), 2),
            ]
        );
        assert_eq!(all(r#""a\"b\\c""#).unwrap()[0].1, "a\"b\\c");
    }

    #[test]
    fn unterminated_string_names_its_line() {
        let err = all("WorldBegin\n\nShape \"sphere\n\"x\"").unwrap_err();
        assert_eq!(err.line, 3);
        assert!(all("\"abc\\").is_err());
    }

    #[test]
    fn huge_tokens_are_refused_with_an_excerpt() {
        let word = format!("WorldBegin\n\nFoo{}", "x".repeat(1 << 20));
        let err = all(&word).unwrap_err();
        assert_eq!(err.line, 3);
        assert!(err.message.contains("1048579 bytes"), "{}", err.message);
        assert!(err.message.len() < 200, "{}", err.message);
        let string = format!("Shape \"{}\"", "y".repeat(MAX_STRING + 1));
        let err = all(&string).unwrap_err();
        assert!(err.message.len() < 200, "{}", err.message);
        let longest = format!(
            "Shape \"{}\" {}",
            "y".repeat(MAX_STRING),
            "1".repeat(MAX_BARE)
        );
        assert_eq!(all(&longest).unwrap().len(), 3);
    }
}
