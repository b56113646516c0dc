//! Arithmetic expressions a user types on the command line (`poa deform --cylindrical
//! 'r + 1.05*z;theta;0.3*z'`).
//!
//! Input: the expression text, the names of its variables (in the order values will be
//! given) and named constants. Output: an [`Expr`] that evaluates in ~100 ns, or an
//! [`ExprError`] that names the 1-based column of the bad token and, for an unknown name,
//! the closest known one.
//!
//! Invariants: evaluation is done by the `exmex` crate (MIT/Apache-2.0); this module only
//! checks the tokens first, so that every mistake it can see gets a column, and rewrites
//! names so that a user's variable can never collide with one of exmex's operators.
//! Angles are radians; `pi` is a constant. Unary minus binds tighter than `^` in exmex, so
//! `-z^2` (which a user means as `-(z^2)`) is refused with the two ways to write it.

use exmex::prelude::*;

/// Functions of one argument the expressions may call (all provided by exmex).
pub const FUNCTIONS: &[&str] = &[
    "sin", "cos", "tan", "asin", "acos", "atan", "sinh", "cosh", "tanh", "sqrt", "exp", "ln",
    "log2", "log10", "abs", "floor", "ceil", "round", "signum",
];

/// What is wrong with an expression, and where (1-based character column).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("column {column}: {message}")]
pub struct ExprError {
    pub column: usize,
    pub message: String,
}

/// A compiled expression over a fixed list of variables.
#[derive(Debug, Clone)]
pub struct Expr {
    text: String,
    flat: FlatEx<f64>,
    /// For each of exmex's variables (alphabetical), the index in the caller's list.
    order: Vec<usize>,
    scratch: std::cell::RefCell<Vec<f64>>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Tok {
    Num,
    Name,
    Op(u8),
    Open,
    Close,
}

fn err(column: usize, message: impl Into<String>) -> ExprError {
    ExprError {
        column,
        message: message.into(),
    }
}

/// The closest of `known` to `name` (edits, swaps counted as one), when close enough to
/// be a likely typo; ties go to a name with the same first letter.
fn suggest<'a>(name: &str, known: impl Iterator<Item = &'a str>) -> Option<&'a str> {
    let first = name.chars().next();
    known
        .map(|k| {
            let d = strsim::damerau_levenshtein(name, k);
            (d, k.chars().next() != first, k)
        })
        .filter(|(d, _, _)| *d <= (name.chars().count() / 3).max(1))
        .min()
        .map(|b| b.2)
}

impl Expr {
    /// Compiles `text` over `vars` (values later given in this order) and `params`
    /// (constants substituted now).
    pub fn compile(text: &str, vars: &[&str], params: &[(&str, f64)]) -> Result<Expr, ExprError> {
        let chars: Vec<char> = text.chars().collect();
        let mut out = String::with_capacity(text.len() + 16);
        let mut toks: Vec<(Tok, usize)> = Vec::new();
        let mut used = Vec::new();
        let mut depth: Vec<usize> = Vec::new();
        let mut i = 0;
        while i < chars.len() {
            let c = chars[i];
            let col = i + 1;
            if c.is_whitespace() {
                out.push(' ');
                i += 1;
                continue;
            }
            if c.is_ascii_digit() || c == '.' {
                let start = i;
                while i < chars.len() && (chars[i].is_ascii_digit() || chars[i] == '.') {
                    i += 1;
                }
                // Scientific notation: 1e-3, 2.5E4.
                if i < chars.len() && (chars[i] == 'e' || chars[i] == 'E') {
                    let mut j = i + 1;
                    if j < chars.len() && (chars[j] == '+' || chars[j] == '-') {
                        j += 1;
                    }
                    if j < chars.len() && chars[j].is_ascii_digit() {
                        while j < chars.len() && chars[j].is_ascii_digit() {
                            j += 1;
                        }
                        i = j;
                    }
                }
                let lit: String = chars[start..i].iter().collect();
                let value: f64 = lit
                    .parse()
                    .map_err(|_| err(col, format!("`{lit}` is not a number")))?;
                if matches!(toks.last(), Some((Tok::Num | Tok::Name | Tok::Close, _))) {
                    return Err(err(col, format!("missing operator before `{lit}`")));
                }
                out.push_str(&format!("{value:?}"));
                toks.push((Tok::Num, col));
                continue;
            }
            if c.is_ascii_alphabetic() || c == '_' {
                let start = i;
                while i < chars.len() && (chars[i].is_ascii_alphanumeric() || chars[i] == '_') {
                    i += 1;
                }
                let name: String = chars[start..i].iter().collect();
                let mut j = i;
                while j < chars.len() && chars[j].is_whitespace() {
                    j += 1;
                }
                let call = j < chars.len() && chars[j] == '(';
                if matches!(toks.last(), Some((Tok::Num | Tok::Name | Tok::Close, _))) {
                    return Err(err(col, format!("missing operator before `{name}`")));
                }
                if call {
                    if !FUNCTIONS.contains(&name.as_str()) {
                        let hint = suggest(&name, FUNCTIONS.iter().copied())
                            .map(|s| format!("; did you mean `{s}`?"))
                            .unwrap_or_default();
                        return Err(err(col, format!("unknown function `{name}`{hint}")));
                    }
                    out.push_str(&name);
                    // A function name is followed by its argument: it acts like an operator.
                    toks.push((Tok::Op(b'f'), col));
                    continue;
                }
                if name == "pi" {
                    out.push_str(&format!("{:?}", std::f64::consts::PI));
                } else if let Some((_, v)) = params.iter().find(|(p, _)| *p == name) {
                    out.push_str(&format!("({v:?})"));
                } else if let Some(k) = vars.iter().position(|v| *v == name) {
                    out.push_str("v_");
                    out.push_str(&name);
                    if !used.contains(&k) {
                        used.push(k);
                    }
                } else {
                    let known = vars
                        .iter()
                        .copied()
                        .chain(params.iter().map(|p| p.0))
                        .chain(std::iter::once("pi"));
                    let hint = suggest(&name, known)
                        .map(|s| format!("; did you mean `{s}`?"))
                        .unwrap_or_default();
                    let names: Vec<&str> = vars
                        .iter()
                        .copied()
                        .chain(params.iter().map(|p| p.0))
                        .collect();
                    return Err(err(
                        col,
                        format!(
                            "unknown name `{name}`{hint} (known: {}, pi)",
                            names.join(", ")
                        ),
                    ));
                }
                toks.push((Tok::Name, col));
                continue;
            }
            match c {
                '+' | '-' | '*' | '/' | '^' => {
                    let unary =
                        !matches!(toks.last(), Some((Tok::Num | Tok::Name | Tok::Close, _)));
                    if unary && c != '-' && c != '+' {
                        return Err(err(col, format!("`{c}` needs a value before it")));
                    }
                    if unary && c == '-' && Self::operand_then_power(&chars, i + 1) {
                        return Err(err(
                            col,
                            "`-a^b` is ambiguous here; write `-(a^b)` or `(-a)^b`",
                        ));
                    }
                    out.push(c);
                    toks.push((Tok::Op(if unary { b'u' } else { c as u8 }), col));
                }
                '(' => {
                    if matches!(toks.last(), Some((Tok::Num | Tok::Name | Tok::Close, _))) {
                        return Err(err(col, "missing operator before `(`"));
                    }
                    depth.push(col);
                    out.push('(');
                    toks.push((Tok::Open, col));
                }
                ')' => {
                    if depth.pop().is_none() {
                        return Err(err(col, "`)` without a matching `(`"));
                    }
                    if !matches!(toks.last(), Some((Tok::Num | Tok::Name | Tok::Close, _))) {
                        return Err(err(col, "a value is missing before `)`"));
                    }
                    out.push(')');
                    toks.push((Tok::Close, col));
                }
                _ => return Err(err(col, format!("unexpected character `{c}`"))),
            }
            i += 1;
        }
        if let Some(open) = depth.pop() {
            return Err(err(open, "`(` is never closed"));
        }
        match toks.last() {
            None => return Err(err(1, "the expression is empty")),
            Some((Tok::Op(_) | Tok::Open, col)) => {
                return Err(err(*col, "the expression ends without a value"))
            }
            _ => {}
        }
        let flat = FlatEx::<f64>::parse(&out)
            .map_err(|e| err(1, format!("cannot read the expression: {e}")))?;
        let order = flat
            .var_names()
            .iter()
            .map(|n| {
                let n = n.strip_prefix("v_").unwrap_or(n);
                vars.iter().position(|v| *v == n).unwrap_or(0)
            })
            .collect();
        Ok(Expr {
            text: text.to_string(),
            flat,
            order,
            scratch: std::cell::RefCell::new(Vec::new()),
        })
    }

    /// Whether `chars[from..]` starts with one operand (number, name, call or group) that
    /// `^` follows.
    fn operand_then_power(chars: &[char], from: usize) -> bool {
        let mut i = from;
        while i < chars.len() && chars[i].is_whitespace() {
            i += 1;
        }
        if i >= chars.len() {
            return false;
        }
        if chars[i].is_ascii_alphanumeric() || chars[i] == '.' || chars[i] == '_' {
            while i < chars.len()
                && (chars[i].is_ascii_alphanumeric() || chars[i] == '.' || chars[i] == '_')
            {
                i += 1;
            }
        }
        while i < chars.len() && chars[i].is_whitespace() {
            i += 1;
        }
        if i < chars.len() && chars[i] == '(' {
            let mut d = 0;
            while i < chars.len() {
                match chars[i] {
                    '(' => d += 1,
                    ')' => {
                        d -= 1;
                        if d == 0 {
                            i += 1;
                            break;
                        }
                    }
                    _ => {}
                }
                i += 1;
            }
        }
        while i < chars.len() && chars[i].is_whitespace() {
            i += 1;
        }
        i < chars.len() && chars[i] == '^'
    }

    /// The value for `values` (in the order of the `vars` given to [`Expr::compile`]).
    /// NaN when the expression is undefined there (e.g. `sqrt(-1)`).
    pub fn eval(&self, values: &[f64]) -> f64 {
        let mut s = self.scratch.borrow_mut();
        s.clear();
        s.extend(
            self.order
                .iter()
                .map(|&k| values.get(k).copied().unwrap_or(0.0)),
        );
        self.flat.eval(&s).unwrap_or(f64::NAN)
    }

    /// The text as the user wrote it.
    pub fn text(&self) -> &str {
        &self.text
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn expressions_evaluate_with_variables_in_the_callers_order() {
        let e = Expr::compile("r + 1.05*z", &["z", "r"], &[]).unwrap();
        assert!((e.eval(&[2.0, 10.0]) - 12.1).abs() < 1e-12);
        let e = Expr::compile("R*sin(z/H) + pi - 1e-3", &["z"], &[("R", 2.0), ("H", 4.0)]).unwrap();
        let want = 2.0 * (0.5f64).sin() + std::f64::consts::PI - 1e-3;
        assert!((e.eval(&[2.0]) - want).abs() < 1e-12);
        for f in FUNCTIONS {
            let e = Expr::compile(&format!("{f}(0.5)"), &[], &[]).unwrap();
            assert!(e.eval(&[]).is_finite(), "{f}");
        }
        assert_eq!(Expr::compile("-(2^2)", &[], &[]).unwrap().eval(&[]), -4.0);
    }

    #[test]
    fn mistakes_name_their_column() {
        let e = Expr::compile("r + 1.05*zz", &["x", "y", "z", "r", "theta"], &[]).unwrap_err();
        assert_eq!(e.column, 10);
        assert!(
            e.message.contains("`zz`") && e.message.contains("did you mean `z`"),
            "{e}"
        );
        let e = Expr::compile("r * sni(theta)", &["r", "theta"], &[]).unwrap_err();
        assert_eq!(e.column, 5);
        assert!(e.message.contains("did you mean `sin`"), "{e}");
        assert_eq!(Expr::compile("r + * 2", &["r"], &[]).unwrap_err().column, 5);
        assert_eq!(Expr::compile("(r + 2", &["r"], &[]).unwrap_err().column, 1);
        assert_eq!(Expr::compile("r + 2)", &["r"], &[]).unwrap_err().column, 6);
        assert_eq!(Expr::compile("r 2", &["r"], &[]).unwrap_err().column, 3);
        assert_eq!(Expr::compile("r +", &["r"], &[]).unwrap_err().column, 3);
        assert_eq!(Expr::compile("r # 2", &["r"], &[]).unwrap_err().column, 3);
        assert_eq!(Expr::compile("", &["r"], &[]).unwrap_err().column, 1);
        let e = Expr::compile("1 - z^2", &["z"], &[]).unwrap();
        assert_eq!(e.eval(&[3.0]), -8.0);
        let e = Expr::compile("-z^2", &["z"], &[]).unwrap_err();
        assert!(e.message.contains("-(a^b)"), "{e}");
    }
}
