//! pbrt-v4's syntactic level: a directive, its positional arguments and its typed parameter list
//! (`"type name" value` or `"type name" [ values ]`), checked for type and arity here so the
//! importer sees only well-formed values.

use super::directives::{self, Form};
use super::tokenizer::{Kind, LexError, Token, Tokenizer};
use crate::files::snippet;
use std::cell::Cell;

/// A syntax or type error and the line it is on.
#[derive(Clone, Debug, PartialEq)]
pub struct ParseError {
    pub line: u32,
    pub message: String,
}

impl From<LexError> for ParseError {
    fn from(e: LexError) -> Self {
        ParseError {
            line: e.line,
            message: e.message,
        }
    }
}

fn err<T>(line: u32, message: impl Into<String>) -> Result<T, ParseError> {
    Err(ParseError {
        line,
        message: message.into(),
    })
}

/// A positional argument.
#[derive(Clone, Debug, PartialEq)]
pub enum Arg {
    Num(f64),
    Str(String),
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ParamType {
    Integer,
    Float,
    Point2,
    Vector2,
    Point3,
    Vector3,
    Normal,
    Rgb,
    Blackbody,
    Spectrum,
    Bool,
    Str,
    Texture,
}

impl ParamType {
    fn parse(s: &str) -> Option<ParamType> {
        Some(match s {
            "integer" => ParamType::Integer,
            "float" => ParamType::Float,
            "point2" => ParamType::Point2,
            "vector2" => ParamType::Vector2,
            "point3" | "point" => ParamType::Point3,
            "vector3" | "vector" => ParamType::Vector3,
            "normal3" | "normal" => ParamType::Normal,
            "rgb" | "color" => ParamType::Rgb,
            "blackbody" => ParamType::Blackbody,
            "spectrum" => ParamType::Spectrum,
            "bool" => ParamType::Bool,
            "string" => ParamType::Str,
            "texture" => ParamType::Texture,
            _ => return None,
        })
    }

    pub fn name(self) -> &'static str {
        match self {
            ParamType::Integer => "integer",
            ParamType::Float => "float",
            ParamType::Point2 => "point2",
            ParamType::Vector2 => "vector2",
            ParamType::Point3 => "point3",
            ParamType::Vector3 => "vector3",
            ParamType::Normal => "normal",
            ParamType::Rgb => "rgb",
            ParamType::Blackbody => "blackbody",
            ParamType::Spectrum => "spectrum",
            ParamType::Bool => "bool",
            ParamType::Str => "string",
            ParamType::Texture => "texture",
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
pub enum Values {
    Nums(Vec<f64>),
    Strs(Vec<String>),
    Bools(Vec<bool>),
}

#[derive(Debug)]
pub struct Param {
    pub ty: ParamType,
    pub name: String,
    pub line: u32,
    pub values: Values,
    used: Cell<bool>,
}

/// A directive's parameters; lookups mark a parameter used, so the rest can be reported.
#[derive(Debug, Default)]
pub struct ParamList {
    pub params: Vec<Param>,
}

/// A spectrum-valued parameter as given.
#[derive(Clone, Debug, PartialEq)]
pub enum Spectrum {
    Rgb([f32; 3]),
    Blackbody(f32),
    /// Wavelength-value pairs.
    Sampled(Vec<f32>),
    Named(String),
}

/// A parameter that may name a texture or give a value.
#[derive(Clone, Debug, PartialEq)]
pub enum TexOr<T> {
    Texture(String),
    Value(T),
}

impl ParamList {
    fn find(&self, name: &str) -> Option<&Param> {
        let p = self.params.iter().find(|p| p.name == name)?;
        p.used.set(true);
        Some(p)
    }

    /// The parameters nobody looked up.
    pub fn unused(&self) -> impl Iterator<Item = &Param> {
        self.params.iter().filter(|p| !p.used.get())
    }

    /// Marks parameters vmerge knows and deliberately does not use, so they are not reported.
    pub fn mark_used(&self, names: &[&str]) {
        for p in &self.params {
            if names.contains(&p.name.as_str()) {
                p.used.set(true);
            }
        }
    }

    pub fn mark_all_used(&self) {
        for p in &self.params {
            p.used.set(true);
        }
    }

    fn typed(&self, name: &str, allowed: &[ParamType]) -> Result<Option<&Param>, ParseError> {
        let Some(p) = self.find(name) else {
            return Ok(None);
        };
        if !allowed.contains(&p.ty) {
            let names: Vec<_> = allowed.iter().map(|t| t.name()).collect();
            return err(
                p.line,
                format!(
                    "parameter '{}' must be of type {}, not {}",
                    snippet(&p.name),
                    names.join(" or "),
                    p.ty.name()
                ),
            );
        }
        Ok(Some(p))
    }

    fn single(&self, p: &Param) -> Result<(), ParseError> {
        let n = match &p.values {
            Values::Nums(v) => v.len(),
            Values::Strs(v) => v.len(),
            Values::Bools(v) => v.len(),
        };
        if n != 1 {
            return err(
                p.line,
                format!(
                    "parameter '{} {}' takes one value, got {n}",
                    p.ty.name(),
                    snippet(&p.name)
                ),
            );
        }
        Ok(())
    }

    pub fn float(&self, name: &str, default: f32) -> Result<f32, ParseError> {
        match self.typed(name, &[ParamType::Float])? {
            None => Ok(default),
            Some(p) => {
                self.single(p)?;
                Ok(p.nums()[0] as f32)
            }
        }
    }

    pub fn int(&self, name: &str, default: i64) -> Result<i64, ParseError> {
        match self.typed(name, &[ParamType::Integer])? {
            None => Ok(default),
            Some(p) => {
                self.single(p)?;
                Ok(p.nums()[0] as i64)
            }
        }
    }

    pub fn bool(&self, name: &str, default: bool) -> Result<bool, ParseError> {
        match self.typed(name, &[ParamType::Bool])? {
            None => Ok(default),
            Some(p) => {
                self.single(p)?;
                match &p.values {
                    Values::Bools(b) => Ok(b[0]),
                    _ => unreachable!("bool parameters hold bools (checked when parsed)"),
                }
            }
        }
    }

    pub fn string(&self, name: &str) -> Result<Option<&str>, ParseError> {
        match self.typed(name, &[ParamType::Str])? {
            None => Ok(None),
            Some(p) => {
                self.single(p)?;
                Ok(Some(&p.strs()[0]))
            }
        }
    }

    /// A list of numbers of one of the `allowed` types, with its line.
    pub fn nums(
        &self,
        name: &str,
        allowed: &[ParamType],
    ) -> Result<Option<(&[f64], u32)>, ParseError> {
        Ok(self.typed(name, allowed)?.map(|p| (p.nums(), p.line)))
    }

    /// A point or vector (3 numbers).
    pub fn vec3(&self, name: &str, default: [f64; 3]) -> Result<[f64; 3], ParseError> {
        let allowed = [ParamType::Point3, ParamType::Vector3, ParamType::Normal];
        match self.typed(name, &allowed)? {
            None => Ok(default),
            Some(p) => {
                let v = p.nums();
                if v.len() != 3 {
                    return err(
                        p.line,
                        format!(
                            "parameter '{}' takes one point, got {}",
                            snippet(&p.name),
                            v.len() / 3
                        ),
                    );
                }
                Ok([v[0], v[1], v[2]])
            }
        }
    }

    pub fn spectrum(&self, name: &str) -> Result<Option<(Spectrum, u32)>, ParseError> {
        let allowed = [ParamType::Rgb, ParamType::Blackbody, ParamType::Spectrum];
        let Some(p) = self.typed(name, &allowed)? else {
            return Ok(None);
        };
        let s = match (p.ty, &p.values) {
            (ParamType::Rgb, Values::Nums(v)) => {
                Spectrum::Rgb([v[0] as f32, v[1] as f32, v[2] as f32])
            }
            (ParamType::Blackbody, Values::Nums(v)) => Spectrum::Blackbody(v[0] as f32),
            (_, Values::Strs(v)) => Spectrum::Named(v[0].clone()),
            (_, Values::Nums(v)) => Spectrum::Sampled(v.iter().map(|&x| x as f32).collect()),
            (_, Values::Bools(_)) => unreachable!("spectra hold numbers or a name"),
        };
        Ok(Some((s, p.line)))
    }

    /// A spectrum or the name of a spectrum texture.
    pub fn spectrum_texture(
        &self,
        name: &str,
    ) -> Result<Option<(TexOr<Spectrum>, u32)>, ParseError> {
        if let Some(p) = self.typed_texture(name)? {
            return Ok(Some(p));
        }
        Ok(self.spectrum(name)?.map(|(s, l)| (TexOr::Value(s), l)))
    }

    /// A float or the name of a float texture.
    pub fn float_texture(&self, name: &str) -> Result<Option<(TexOr<f32>, u32)>, ParseError> {
        if let Some(p) = self.typed_texture(name)? {
            return Ok(Some(p));
        }
        let Some(p) = self.typed(name, &[ParamType::Float])? else {
            return Ok(None);
        };
        self.single(p)?;
        Ok(Some((TexOr::Value(p.nums()[0] as f32), p.line)))
    }

    fn typed_texture<T>(&self, name: &str) -> Result<Option<(TexOr<T>, u32)>, ParseError> {
        match self.params.iter().find(|p| p.name == name) {
            Some(p) if p.ty == ParamType::Texture => {
                p.used.set(true);
                self.single(p)?;
                Ok(Some((TexOr::Texture(p.strs()[0].clone()), p.line)))
            }
            _ => Ok(None),
        }
    }
}

impl Param {
    fn nums(&self) -> &[f64] {
        match &self.values {
            Values::Nums(v) => v,
            _ => &[],
        }
    }

    fn strs(&self) -> &[String] {
        match &self.values {
            Values::Strs(v) => v,
            _ => &[],
        }
    }
}

#[derive(Debug)]
pub struct Directive {
    pub name: String,
    pub line: u32,
    pub args: Vec<Arg>,
    pub params: ParamList,
}

impl Directive {
    /// The `i`-th positional string (the parser checked it is one).
    pub fn str_arg(&self, i: usize) -> &str {
        match &self.args[i] {
            Arg::Str(s) => s,
            Arg::Num(_) => unreachable!("checked by the parser"),
        }
    }

    /// The positional numbers (the parser checked their count).
    pub fn num_args(&self) -> Vec<f64> {
        self.args
            .iter()
            .filter_map(|a| match a {
                Arg::Num(x) => Some(*x),
                Arg::Str(_) => None,
            })
            .collect()
    }
}

/// What follows `name`, from the table of directives.
fn form(name: &str) -> Option<Form> {
    directives::find(name).map(|spec| spec.form)
}

pub struct Parser<'a> {
    tokens: Tokenizer<'a>,
}

impl<'a> Parser<'a> {
    pub fn new(src: &'a str) -> Self {
        Parser {
            tokens: Tokenizer::new(src),
        }
    }

    /// The next directive; `Ok(None)` at the end of the file. An unknown directive name is
    /// returned with its arguments skipped and `args`/`params` empty, for the caller to warn.
    pub fn next_directive(&mut self) -> Result<Option<Directive>, ParseError> {
        let Some(tok) = self.tokens.next()? else {
            return Ok(None);
        };
        if tok.kind != Kind::Bare || tok.is_number() {
            return err(
                tok.line,
                format!("expected a directive, found {}", describe(&tok)),
            );
        }
        let mut d = Directive {
            name: tok.text.to_string(),
            line: tok.line,
            args: Vec::new(),
            params: ParamList::default(),
        };
        let Some(form) = form(tok.text) else {
            self.skip_arguments()?;
            return Ok(Some(d));
        };
        match form {
            Form::Nothing => {}
            Form::Numbers(n) => {
                for _ in 0..n {
                    d.args.push(Arg::Num(self.number(&d)?));
                }
            }
            Form::Matrix => {
                let bracket = matches!(self.tokens.peek()?, Some(t) if t.kind == Kind::Open);
                if bracket {
                    self.tokens.next()?;
                }
                for _ in 0..16 {
                    d.args.push(Arg::Num(self.number(&d)?));
                }
                if bracket {
                    match self.tokens.next()? {
                        Some(t) if t.kind == Kind::Close => {}
                        Some(t) => {
                            return err(
                                t.line,
                                format!(
                                    "{}: a matrix has 16 numbers, found {} after them",
                                    d.name,
                                    describe(&t)
                                ),
                            )
                        }
                        None => return err(self.tokens.line(), format!("{}: missing ']'", d.name)),
                    }
                }
            }
            Form::Strings(n) | Form::StringsParams(n) => {
                for _ in 0..n {
                    d.args.push(Arg::Str(self.string(&d)?));
                }
            }
            Form::Word => {
                let t = self.tokens.next()?;
                match t {
                    Some(t) if t.kind == Kind::Bare && !t.is_number() => {
                        d.args.push(Arg::Str(t.text.to_string()))
                    }
                    _ => return err(d.line, format!("{} needs a word argument", d.name)),
                }
            }
            Form::OneOrTwoStrings => {
                d.args.push(Arg::Str(self.string(&d)?));
                if matches!(self.tokens.peek()?, Some(t) if t.kind == Kind::Str) {
                    d.args.push(Arg::Str(self.string(&d)?));
                }
            }
            Form::ParamsOnly => {}
        }
        if matches!(form, Form::StringsParams(_) | Form::ParamsOnly) {
            d.params = self.params()?;
        }
        Ok(Some(d))
    }

    fn number(&mut self, d: &Directive) -> Result<f64, ParseError> {
        match self.tokens.next()? {
            Some(t) if t.is_number() => parse_number(&t),
            Some(t) => err(
                t.line,
                format!("{} expects a number, found {}", d.name, describe(&t)),
            ),
            None => err(
                self.tokens.line(),
                format!("{} expects a number, found the end of the file", d.name),
            ),
        }
    }

    fn string(&mut self, d: &Directive) -> Result<String, ParseError> {
        match self.tokens.next()? {
            Some(t) if t.kind == Kind::Str => Ok(t.unescaped().into_owned()),
            Some(t) => err(
                t.line,
                format!("{} expects a quoted string, found {}", d.name, describe(&t)),
            ),
            None => err(
                self.tokens.line(),
                format!(
                    "{} expects a quoted string, found the end of the file",
                    d.name
                ),
            ),
        }
    }

    /// Skips an unknown directive's arguments: everything up to the next bare word that is not
    /// a number or a bool.
    fn skip_arguments(&mut self) -> Result<(), ParseError> {
        let mut depth = 0u32;
        while let Some(t) = self.tokens.peek()? {
            match t.kind {
                Kind::Open => depth += 1,
                Kind::Close => depth = depth.saturating_sub(1),
                Kind::Bare
                    if depth == 0 && !t.is_number() && !matches!(t.text, "true" | "false") =>
                {
                    return Ok(())
                }
                _ => {}
            }
            self.tokens.next()?;
        }
        Ok(())
    }

    fn params(&mut self) -> Result<ParamList, ParseError> {
        let mut list = ParamList::default();
        while let Some(decl) = self.tokens.peek()? {
            if decl.kind != Kind::Str {
                break;
            }
            self.tokens.next()?;
            let text = decl.unescaped();
            let mut words = text.split_whitespace();
            let (Some(ty), Some(name), None) = (words.next(), words.next(), words.next()) else {
                return err(
                    decl.line,
                    format!(
                        "parameter declaration \"{}\" is not of the form \"type name\"",
                        snippet(&text)
                    ),
                );
            };
            let Some(ty) = ParamType::parse(ty) else {
                return err(
                    decl.line,
                    format!(
                        "unknown parameter type '{}' in \"{}\"",
                        snippet(ty),
                        snippet(&text)
                    ),
                );
            };
            if list.params.iter().any(|p| p.name == name) {
                return err(
                    decl.line,
                    format!("parameter '{}' given twice", snippet(name)),
                );
            }
            let values = self.values(&decl, &text)?;
            let values = check(ty, name, values, decl.line)?;
            list.params.push(Param {
                ty,
                name: name.to_string(),
                line: decl.line,
                values,
                used: Cell::new(false),
            });
        }
        Ok(list)
    }

    /// One value or a bracketed list, gathered without regard to the declared type.
    fn values(&mut self, decl: &Token, text: &str) -> Result<Vec<Value>, ParseError> {
        let first = self.tokens.next()?;
        let Some(first) = first else {
            return err(
                decl.line,
                format!("parameter \"{}\" has no value", snippet(text)),
            );
        };
        if first.kind != Kind::Open {
            return Ok(vec![value(&first, text)?]);
        }
        let mut out = Vec::new();
        loop {
            match self.tokens.next()? {
                Some(t) if t.kind == Kind::Close => return Ok(out),
                Some(t) => out.push(value(&t, text)?),
                None => {
                    return err(
                        first.line,
                        format!("parameter \"{}\": '[' is never closed", snippet(text)),
                    )
                }
            }
        }
    }
}

enum Value {
    Num(f64),
    Str(String),
    Bool(bool),
}

fn value(t: &Token, decl: &str) -> Result<Value, ParseError> {
    match t.kind {
        Kind::Str => Ok(Value::Str(t.unescaped().into_owned())),
        Kind::Bare if t.is_number() => Ok(Value::Num(parse_number(t)?)),
        Kind::Bare if t.text == "true" => Ok(Value::Bool(true)),
        Kind::Bare if t.text == "false" => Ok(Value::Bool(false)),
        _ => err(
            t.line,
            format!(
                "parameter \"{}\": unexpected {} among its values",
                snippet(decl),
                describe(t)
            ),
        ),
    }
}

fn parse_number(t: &Token) -> Result<f64, ParseError> {
    match t.text.parse::<f64>() {
        Ok(x) if x.is_finite() => Ok(x),
        _ => err(
            t.line,
            format!("'{}' is not a finite number", snippet(t.text)),
        ),
    }
}

fn describe(t: &Token) -> String {
    match t.kind {
        Kind::Str => format!("the string \"{}\"", snippet(t.text)),
        Kind::Open => "'['".into(),
        Kind::Close => "']'".into(),
        Kind::Bare => format!("'{}'", snippet(t.text)),
    }
}

/// Checks the values against the declared type and arity.
fn check(ty: ParamType, name: &str, values: Vec<Value>, line: u32) -> Result<Values, ParseError> {
    let what = format!("parameter '{} {}'", ty.name(), snippet(name));
    if values.is_empty() {
        return err(line, format!("{what} has no values"));
    }
    let all_nums = values.iter().all(|v| matches!(v, Value::Num(_)));
    let all_strs = values.iter().all(|v| matches!(v, Value::Str(_)));
    let nums = || -> Vec<f64> {
        values
            .iter()
            .filter_map(|v| match v {
                Value::Num(x) => Some(*x),
                _ => None,
            })
            .collect()
    };
    let strs = |values: Vec<Value>| -> Vec<String> {
        values
            .into_iter()
            .filter_map(|v| match v {
                Value::Str(s) => Some(s),
                _ => None,
            })
            .collect()
    };
    let n = values.len();
    let multiple = |k: usize| -> Result<(), ParseError> {
        if !n.is_multiple_of(k) {
            return err(
                line,
                format!("{what} needs a multiple of {k} numbers, got {n}"),
            );
        }
        Ok(())
    };
    match ty {
        ParamType::Integer
        | ParamType::Float
        | ParamType::Point2
        | ParamType::Vector2
        | ParamType::Point3
        | ParamType::Vector3
        | ParamType::Normal
        | ParamType::Rgb
        | ParamType::Blackbody => {
            if !all_nums {
                return err(line, format!("{what} takes numbers only"));
            }
            match ty {
                ParamType::Point2 | ParamType::Vector2 => multiple(2)?,
                ParamType::Point3 | ParamType::Vector3 | ParamType::Normal => multiple(3)?,
                ParamType::Rgb if n != 3 => {
                    return err(line, format!("{what} takes 3 numbers, got {n}"))
                }
                ParamType::Blackbody if n != 1 => {
                    return err(line, format!("{what} takes 1 temperature, got {n}"))
                }
                _ => {}
            }
            let v = nums();
            // Positions keep f64 until their own bound is checked.
            if ty != ParamType::Point3 {
                within_f32(&what, &v, line)?;
            }
            if ty == ParamType::Integer {
                if let Some(x) = v.iter().find(|x| x.fract() != 0.0 || x.abs() > 2e9) {
                    return err(line, format!("{what}: {x} is not an integer"));
                }
            }
            Ok(Values::Nums(v))
        }
        ParamType::Spectrum => {
            if all_strs && n == 1 {
                Ok(Values::Strs(strs(values)))
            } else if all_nums {
                multiple(2)?;
                let v = nums();
                within_f32(&what, &v, line)?;
                Ok(Values::Nums(v))
            } else {
                err(
                    line,
                    format!("{what} takes wavelength-value pairs or one name"),
                )
            }
        }
        ParamType::Bool => {
            let mut out = Vec::with_capacity(n);
            for v in values {
                out.push(match v {
                    Value::Bool(b) => b,
                    Value::Str(s) if s == "true" => true,
                    Value::Str(s) if s == "false" => false,
                    _ => return err(line, format!("{what} takes true or false")),
                });
            }
            Ok(Values::Bools(out))
        }
        ParamType::Str | ParamType::Texture => {
            if !all_strs {
                return err(line, format!("{what} takes quoted strings"));
            }
            Ok(Values::Strs(strs(values)))
        }
    }
}

/// Refuses a number that would become infinite as the f32 it is stored as.
fn within_f32(what: &str, values: &[f64], line: u32) -> Result<(), ParseError> {
    match values.iter().find(|x| x.abs() > f64::from(f32::MAX)) {
        Some(x) => err(
            line,
            format!("{what}: {x:e} is beyond the range of 32-bit floats (3.4e38)"),
        ),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse_all(src: &str) -> Result<Vec<Directive>, ParseError> {
        let mut p = Parser::new(src);
        let mut out = Vec::new();
        while let Some(d) = p.next_directive()? {
            out.push(d);
        }
        Ok(out)
    }

    #[test]
    fn directives_arguments_and_parameters() {
        let src = "LookAt 0 1 2  3 4 5\n 0 1 0\nTransform [ 1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1 ]\n\
                   Texture \"t\" \"spectrum\" \"imagemap\" \"string filename\" \"a b.tga\"\n\
                   MakeNamedMaterial \"m\" \"string type\" [ \"diffuse\" ]\n  \"bool x\" false \"rgb reflectance\" [0.1 0.2 0.3]\n";
        let ds = parse_all(src).unwrap();
        assert_eq!(ds.len(), 4);
        assert_eq!(ds[0].num_args().len(), 9);
        assert_eq!(ds[1].num_args().len(), 16);
        assert_eq!(ds[2].str_arg(2), "imagemap");
        assert_eq!(ds[2].params.string("filename").unwrap(), Some("a b.tga"));
        let m = &ds[3];
        assert_eq!(m.line, 5);
        assert!(!m.params.bool("x", true).unwrap());
        assert_eq!(
            m.params.spectrum("reflectance").unwrap(),
            Some((Spectrum::Rgb([0.1, 0.2, 0.3]), 6))
        );
        assert_eq!(m.params.unused().count(), 1);
    }

    #[test]
    fn type_and_arity_errors_name_their_line() {
        let line = |src: &str| parse_all(src).unwrap_err().line;
        assert_eq!(line("Shape \"sphere\"\n \"float radius\" [ \"one\" ]"), 2);
        assert_eq!(line("Shape \"x\"\n\n \"rgb L\" [ 1 2 ]"), 3);
        assert_eq!(line("Shape \"x\" \"point3 P\" [ 1 2 ]"), 1);
        assert_eq!(line("Shape \"x\" \"integer indices\" [ 0 1.5 2 ]"), 1);
        assert_eq!(line("Shape \"x\" \"flaot radius\" 1"), 1);
        assert_eq!(line("Shape \"x\" \"float radius\" [ 1\nWorldBegin"), 2);
        assert_eq!(line("Shape \"x\" \"float radius\" [ 1\n2\n"), 1);
        assert_eq!(line("Translate 1 2\nWorldBegin"), 2);
        assert_eq!(line("Shape \"x\" \"float radius\" 1 \"float radius\" 2"), 1);
        // Numbers that are finite as f64 but not as the f32 they are stored as.
        assert_eq!(line("Shape \"x\"\n \"float radius\" 1e39"), 2);
        assert_eq!(line("Shape \"x\" \"rgb L\" [ 1 1 -1e39 ]"), 1);
        assert_eq!(line("Shape \"x\" \"spectrum L\" [ 400 1e300 ]"), 1);
        assert!(parse_all("Shape \"x\" \"point3 P\" [ 0 0 1e39 ]").is_ok());
        // Type checks at lookup: a float wanted, an integer given.
        let ds = parse_all("Shape \"sphere\" \"integer radius\" 1").unwrap();
        assert!(ds[0].params.float("radius", 1.0).is_err());
    }

    #[test]
    fn unknown_directives_are_skipped_whole() {
        let ds = parse_all("Frobnicate \"a\" [ 1 2 ] 3 true\nWorldBegin").unwrap();
        assert_eq!(ds.len(), 2);
        assert_eq!(ds[0].name, "Frobnicate");
        assert_eq!(ds[1].name, "WorldBegin");
    }
}
