//! Fractional transfer functions `G(s) = (sum_i b_i s^beta_i) / (sum_j a_j s^alpha_j) exp(-tau s)`
//! (FOMCON's `fotf`), their exact frequency response and a parser for the form people write.

use crate::error::{finite, invalid, Error, Result};
use num_complex::Complex64;
use std::fmt;
use std::str::FromStr;

/// One term `coef * s^order` of a fractional polynomial.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Term {
    /// The coefficient.
    pub coef: f64,
    /// The (real, non-negative) order of `s`.
    pub order: f64,
}

impl Term {
    /// `coef * s^order`.
    pub const fn new(coef: f64, order: f64) -> Self {
        Self { coef, order }
    }
}

/// A fractional transfer function with input delay:
/// `G(s) = (sum_i num_i.coef s^num_i.order) / (sum_j den_j.coef s^den_j.order) * exp(-delay s)`.
///
/// Terms are kept sorted by decreasing order, like orders merged, zero coefficients dropped.
///
/// ```
/// use fracsim::FracTf;
/// let g: FracTf = "6.77/(0.000028 s^1.78 + 0.0064 s^0.89 + 1)".parse().unwrap();
/// assert!((g.dc_gain() - 6.77).abs() < 1e-12);
/// let h = g.freq_response(100.0); // omega in rad/s
/// assert!(h.norm() < 6.77);
/// ```
#[derive(Debug, Clone)]
pub struct FracTf {
    /// Numerator terms `b_i s^beta_i`.
    pub num: Vec<Term>,
    /// Denominator terms `a_j s^alpha_j`.
    pub den: Vec<Term>,
    /// Input delay `tau` in seconds.
    pub delay: f64,
    /// The factors of a series connection the model is also known as (see
    /// [`FracTf::factors`]); empty when none.
    factors: Vec<FracTf>,
    /// Whether `Display` writes the factors ([`FracTf::with_factors`]) rather than the product
    /// multiplied out.
    show_factors: bool,
    /// The direct feed-through `D` the model is written with, `D + G(s)` ([`FracTf::with_direct`]).
    direct: Option<f64>,
}

/// Equal terms and delay (the factors known are a way of computing, not part of the model).
impl PartialEq for FracTf {
    fn eq(&self, o: &Self) -> bool {
        self.num == o.num && self.den == o.den && self.delay == o.delay
    }
}

/// Frequencies (rad/s) at which a factorisation is checked against the model.
const FACTOR_CHECK_RAD_S: [f64; 8] = [1.23e-3, 1.23e-2, 0.123, 1.23, 12.3, 123.0, 1234.0, 12345.0];

/// Whether the product of `factors` (at least two, their delays aside) is `tf` (its delay aside)
/// within `1e-9` relative at [`FACTOR_CHECK_RAD_S`].
fn factors_match(tf: &FracTf, factors: &[FracTf]) -> bool {
    factors.len() >= 2
        && FACTOR_CHECK_RAD_S.iter().all(|&w| {
            let rational = |g: &FracTf| {
                let eval = |t: &[Term]| -> Complex64 {
                    t.iter().map(|t| jw_pow(w, t.order) * t.coef).sum()
                };
                eval(&g.num) / eval(&g.den)
            };
            let whole = rational(tf);
            let product: Complex64 = factors.iter().map(rational).product();
            (product - whole).norm() <= 1e-9 * whole.norm() && whole.norm().is_finite()
        })
}

fn normalise(what: &'static str, terms: &[Term]) -> Result<Vec<Term>> {
    let mut out: Vec<Term> = Vec::with_capacity(terms.len());
    for t in terms {
        finite(what, t.coef)?;
        finite("order", t.order)?;
        if t.order < 0.0 {
            return invalid(
                "order",
                format!(
                    "{} is negative; move s^{} to the other side",
                    t.order, -t.order
                ),
            );
        }
        if t.order > 20.0 {
            return invalid("order", format!("{} is larger than 20", t.order));
        }
        if t.coef == 0.0 {
            continue;
        }
        match out.iter_mut().find(|o| (o.order - t.order).abs() < 1e-12) {
            Some(o) => o.coef += t.coef,
            None => out.push(*t),
        }
    }
    out.retain(|t| t.coef != 0.0);
    out.sort_by(|a, b| b.order.total_cmp(&a.order));
    Ok(out)
}

impl FracTf {
    /// Build and validate a transfer function.
    ///
    /// # Errors
    /// Non-finite coefficients, orders or delay; negative orders or delay; a denominator with no
    /// nonzero term ([`Error::ZeroDenominator`]).
    pub fn new(num: Vec<Term>, den: Vec<Term>, delay: f64) -> Result<Self> {
        let num = normalise("numerator coefficient", &num)?;
        let den = normalise("denominator coefficient", &den)?;
        if den.is_empty() {
            return Err(Error::ZeroDenominator);
        }
        finite("delay", delay)?;
        if delay < 0.0 {
            return invalid(
                "delay",
                format!("{delay} s is negative (a non-causal model)"),
            );
        }
        Ok(Self {
            num,
            den,
            delay,
            factors: vec![],
            show_factors: false,
            direct: None,
        })
    }

    /// The same model, known as the series connection of `factors` (their delays are ignored:
    /// the model's own is the whole delay). The simulators use the factors where the product
    /// multiplied out cannot be put in pole-residue form (a two-mass drive train's nine-term
    /// denominator: [`crate::Simulator::from_factors`]), and `Display` writes them, `F1 * F2`,
    /// which the parser reads back as the same model and the same factors.
    ///
    /// ```
    /// use fracsim::FracTf;
    /// let a: FracTf = "2/(0.1 s^0.8 + 1)".parse().unwrap();
    /// let b: FracTf = "(0.01 s^2 + 1)/(0.005 s^2 + 0.001 s^0.5 + 1)".parse().unwrap();
    /// let ab: FracTf = "2*(0.01 s^2 + 1)/((0.1 s^0.8 + 1)*(0.005 s^2 + 0.001 s^0.5 + 1))".parse().unwrap();
    /// let g = ab.clone().with_factors(vec![a, b]).unwrap();
    /// let back: FracTf = g.to_string().parse().unwrap();
    /// assert_eq!(back, ab);
    /// assert_eq!(back.factors().len(), 2);
    /// ```
    ///
    /// # Errors
    /// [`Error::Invalid`] when fewer than two factors are given or their product is not the model.
    pub fn with_factors(mut self, factors: Vec<FracTf>) -> Result<Self> {
        if !factors_match(&self, &factors) {
            return invalid("factors", "their product is not the model");
        }
        self.factors = factors
            .into_iter()
            .map(|mut f| {
                f.delay = 0.0;
                f.factors.clear();
                f.show_factors = false;
                f
            })
            .collect();
        self.show_factors = true;
        Ok(self)
    }

    /// The same model, written as its direct feed-through `d` plus a strictly proper rest,
    /// `d + N_r(s)/A(s)` (`N_r = N - d A`), which the parser reads back as the same model. It
    /// changes only how the model is written.
    ///
    /// ```
    /// use fracsim::FracTf;
    /// let g: FracTf = "2 + 6.77/(0.000028 s^1.78 + 0.0064 s^0.89 + 1)".parse().unwrap();
    /// let shown = g.clone().with_direct(2.0).unwrap();
    /// assert_eq!(shown.to_string(), "2 + 6.77/(0.000028 s^1.78 + 0.0064 s^0.89 + 1)");
    /// assert_eq!(shown.to_string().parse::<FracTf>().unwrap(), g);
    /// assert!(g.with_direct(3.0).is_err());
    /// ```
    ///
    /// # Errors
    /// [`Error::Invalid`] when `N - d A` keeps a term of the denominator's highest order (`d` is
    /// not the feed-through) or `d` is not finite.
    pub fn with_direct(mut self, d: f64) -> Result<Self> {
        finite("feed-through", d)?;
        self.direct = None;
        if self.direct_rest(d).is_none() {
            return invalid(
                "feed-through",
                format!("{d} is not the model's feed-through"),
            );
        }
        self.direct = Some(d);
        Ok(self)
    }

    /// `N - d A` with the terms that cancel (within 1e-9 of the largest) dropped, when no term
    /// of the denominator's highest order is left.
    fn direct_rest(&self, d: f64) -> Option<Vec<Term>> {
        let mut rest = self.num.clone();
        for t in &self.den {
            match rest.iter_mut().find(|r| (r.order - t.order).abs() < 1e-12) {
                Some(r) => r.coef -= d * t.coef,
                None => rest.push(Term::new(-d * t.coef, t.order)),
            }
        }
        let big = self
            .num
            .iter()
            .map(|t| t.coef.abs())
            .chain(self.den.iter().map(|t| (d * t.coef).abs()))
            .fold(0.0, f64::max);
        rest.retain(|t| t.coef.abs() > 1e-9 * big);
        rest.sort_by(|a, b| b.order.total_cmp(&a.order));
        let top = self.den_order();
        rest.iter().all(|t| t.order < top - 1e-12).then_some(rest)
    }

    /// The factors of a series connection the model is known as (given by
    /// [`FracTf::with_factors`], or read from a product `F1 * F2 * ..` at the top of the text),
    /// when their product is still the model; else none.
    pub fn factors(&self) -> &[FracTf] {
        if factors_match(self, &self.factors) {
            &self.factors
        } else {
            &[]
        }
    }

    /// The PMSM structure of the reference paper (eq. 10):
    /// `K / (a2 s^(zeta+theta) + a1 s^zeta + 1)`.
    ///
    /// ```
    /// let g = fracsim::FracTf::pmsm(6.82, 0.0059, 2.655e-5, 0.92, 0.8252).unwrap();
    /// assert_eq!(g.den.len(), 3);
    /// assert!((g.den[0].order - 1.7452).abs() < 1e-12);
    /// ```
    ///
    /// # Errors
    /// As [`FracTf::new`].
    pub fn pmsm(k: f64, a1: f64, a2: f64, zeta: f64, theta: f64) -> Result<Self> {
        Self::new(
            vec![Term::new(k, 0.0)],
            vec![
                Term::new(a2, zeta + theta),
                Term::new(a1, zeta),
                Term::new(1.0, 0.0),
            ],
            0.0,
        )
    }

    /// The same model with another input delay (seconds).
    ///
    /// # Errors
    /// A negative or non-finite delay.
    pub fn with_delay(mut self, delay: f64) -> Result<Self> {
        finite("delay", delay)?;
        if delay < 0.0 {
            return invalid("delay", format!("{delay} s is negative"));
        }
        self.delay = delay;
        Ok(self)
    }

    /// The exact frequency response `G(j omega)`, omega in rad/s, with
    /// `(j w)^a = w^a (cos(a pi/2) + j sin(a pi/2))`.
    pub fn freq_response(&self, omega: f64) -> Complex64 {
        let eval = |terms: &[Term]| -> Complex64 {
            terms.iter().map(|t| jw_pow(omega, t.order) * t.coef).sum()
        };
        let g = eval(&self.num) / eval(&self.den);
        if self.delay != 0.0 {
            g * Complex64::from_polar(1.0, -omega * self.delay)
        } else {
            g
        }
    }

    /// [`FracTf::freq_response`] at each omega (rad/s).
    pub fn bode(&self, omega: &[f64]) -> Vec<Complex64> {
        omega.iter().map(|&w| self.freq_response(w)).collect()
    }

    /// The static gain `G(0)`: `b_0 / a_0` from the order-zero terms; `+-inf` for a model that
    /// integrates (no order-zero denominator term), `0` for one that differentiates.
    pub fn dc_gain(&self) -> f64 {
        let at0 = |terms: &[Term]| -> f64 {
            terms
                .iter()
                .filter(|t| t.order == 0.0)
                .map(|t| t.coef)
                .sum()
        };
        let (b, a) = (at0(&self.num), at0(&self.den));
        if a == 0.0 {
            if b == 0.0 {
                let lowest = |t: &[Term]| t.iter().map(|t| t.order).fold(f64::INFINITY, f64::min);
                if lowest(&self.num) > lowest(&self.den) {
                    0.0
                } else {
                    f64::INFINITY
                }
            } else {
                f64::INFINITY.copysign(b * self.den.last().map_or(1.0, |t| t.coef))
            }
        } else {
            b / a
        }
    }

    /// The highest order in the denominator.
    pub fn den_order(&self) -> f64 {
        self.den.first().map_or(0.0, |t| t.order)
    }

    /// The highest order in the numerator (0 for a zero numerator).
    pub fn num_order(&self) -> f64 {
        self.num.first().map_or(0.0, |t| t.order)
    }

    /// Strictly proper: the numerator's highest order below the denominator's (by more than
    /// `1e-9`), so that the output has no instant response to the input (it is continuous where
    /// a held input steps).
    pub fn is_strictly_proper(&self) -> bool {
        self.num_order() + 1e-9 < self.den_order()
    }

    /// Refuse an improper model (numerator order above the denominator's) for simulation: its
    /// response to a held (stepwise) input holds impulses and derivatives of the steps, which no
    /// sampled simulation represents. Its frequency response is fine (the Bode fits may use it).
    ///
    /// ```
    /// let g: fracsim::FracTf = "s^3/(s + 1)".parse().unwrap();
    /// assert!(g.check_proper().is_err());
    /// let g: fracsim::FracTf = "(s + 2)/(s + 1)".parse().unwrap();
    /// assert!(g.check_proper().is_ok());
    /// ```
    ///
    /// # Errors
    /// [`Error::Invalid`] for a numerator order above the denominator order.
    pub fn check_proper(&self) -> Result<()> {
        if self.num_order() > self.den_order() + 1e-12 {
            return invalid(
                "model",
                format!(
                    "{self} is improper (numerator order {} > denominator order {}): its \
                     response to a held input holds impulses, so it cannot be simulated; a \
                     proper model has numerator order <= denominator order",
                    self.num_order(),
                    self.den_order()
                ),
            );
        }
        Ok(())
    }
}

/// `(j omega)^a = omega^a (cos(a pi/2) + j sin(a pi/2))`.
pub fn jw_pow(omega: f64, a: f64) -> Complex64 {
    if a == 0.0 {
        return Complex64::new(1.0, 0.0);
    }
    Complex64::from_polar(omega.powf(a), a * std::f64::consts::FRAC_PI_2)
}

fn fmt_num(x: f64) -> String {
    format!("{x}")
}

fn fmt_poly(terms: &[Term]) -> String {
    if terms.is_empty() {
        return "0".into();
    }
    let mut s = String::new();
    for (i, t) in terms.iter().enumerate() {
        let (sign, c) = if t.coef < 0.0 {
            ("-", -t.coef)
        } else {
            ("+", t.coef)
        };
        if i > 0 {
            s.push_str(&format!(" {sign} "));
        } else if sign == "-" {
            s.push('-');
        }
        if t.order == 0.0 {
            s.push_str(&fmt_num(c));
        } else {
            if c != 1.0 {
                s.push_str(&fmt_num(c));
                s.push(' ');
            }
            if t.order == 1.0 {
                s.push('s');
            } else {
                s.push_str(&format!("s^{}", fmt_num(t.order)));
            }
        }
    }
    s
}

impl fmt::Display for FracTf {
    /// The form [`FracTf::from_str`] reads back: `6.82/(2.655e-5 s^1.7452 + 0.0059 s^0.92 + 1)`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(rest) = self
            .direct
            .and_then(|d| self.direct_rest(d).map(|r| (d, r)))
        {
            let (d, mut num) = rest;
            let open = if self.delay != 0.0 { "(" } else { "" };
            // A single negative term is subtracted: `2 - 6.77/(..)`, not `2 + -6.77/(..)`.
            let minus = num.len() == 1 && num[0].coef < 0.0;
            if minus {
                num[0].coef = -num[0].coef;
            }
            write!(f, "{open}{} {} ", fmt_num(d), if minus { '-' } else { '+' })?;
            let n = fmt_poly(&num);
            if num.len() > 1 {
                write!(f, "({n})")?;
            } else {
                write!(f, "{n}")?;
            }
            write!(f, "/({})", fmt_poly(&self.den))?;
            if self.delay != 0.0 {
                write!(f, ") exp(-{} s)", fmt_num(self.delay))?;
            }
            return Ok(());
        }
        if self.show_factors && !self.factors().is_empty() {
            for (i, g) in self.factors.iter().enumerate() {
                if i > 0 {
                    write!(f, " * ")?;
                }
                write!(f, "{g}")?;
            }
            if self.delay != 0.0 {
                write!(f, " exp(-{} s)", fmt_num(self.delay))?;
            }
            return Ok(());
        }
        let num = fmt_poly(&self.num);
        if self.num.len() > 1 {
            write!(f, "({num})")?;
        } else {
            write!(f, "{num}")?;
        }
        write!(f, "/({})", fmt_poly(&self.den))?;
        if self.delay != 0.0 {
            write!(f, " exp(-{} s)", fmt_num(self.delay))?;
        }
        Ok(())
    }
}

// ---------------------------------------------------------------------------------------------
// Parser: a small recursive-descent parser over rational expressions in `s` with fractional
// powers, products, quotients and `exp(-tau s)` factors. Values are kept as (num, den, delay).

#[derive(Debug, Clone, PartialEq)]
enum Tok {
    Num(f64),
    S,
    Exp,
    Plus,
    Minus,
    Star,
    Slash,
    Caret,
    LParen,
    RParen,
}

impl Tok {
    /// The token in words, for messages.
    fn describe(&self) -> String {
        match self {
            Tok::Num(v) => format!("the number {}", shorten(&v.to_string())),
            Tok::S => "'s'".into(),
            Tok::Exp => "'exp'".into(),
            Tok::Plus => "'+'".into(),
            Tok::Minus => "'-'".into(),
            Tok::Star => "'*'".into(),
            Tok::Slash => "'/'".into(),
            Tok::Caret => "'^'".into(),
            Tok::LParen => "'('".into(),
            Tok::RParen => "')'".into(),
        }
    }
}

/// `s` quoted in a message: at most 24 characters, a longer text cut with its length said.
fn shorten(s: &str) -> String {
    let n = s.chars().count();
    if n <= 24 {
        s.to_string()
    } else {
        format!(
            "{}... ({n} characters)",
            s.chars().take(16).collect::<String>()
        )
    }
}

fn perr<T>(pos: usize, msg: impl Into<String>) -> Result<T> {
    Err(Error::Parse {
        pos,
        msg: msg.into(),
    })
}

fn lex(src: &str) -> Result<Vec<(usize, Tok)>> {
    let b = src.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let c = b[i];
        let start = i;
        match c {
            b' ' | b'\t' | b'\n' | b'\r' => {
                i += 1;
                continue;
            }
            b'+' => out.push((i, Tok::Plus)),
            b'-' => out.push((i, Tok::Minus)),
            b'*' if b.get(i + 1) == Some(&b'*') => {
                return perr(i, "'**' is not supported: write powers as s^a (e.g. s^0.5)")
            }
            b'*' => out.push((i, Tok::Star)),
            b'/' => out.push((i, Tok::Slash)),
            b'^' => out.push((i, Tok::Caret)),
            b'(' | b'[' => out.push((i, Tok::LParen)),
            b')' | b']' => out.push((i, Tok::RParen)),
            b'0'..=b'9' | b'.' => {
                while i < b.len() && (b[i].is_ascii_digit() || b[i] == b'.') {
                    i += 1;
                }
                // exponent: e or E followed by optional sign and at least one digit
                if i < b.len() && (b[i] == b'e' || b[i] == b'E') {
                    let mut j = i + 1;
                    if j < b.len() && (b[j] == b'+' || b[j] == b'-') {
                        j += 1;
                    }
                    if j < b.len() && b[j].is_ascii_digit() {
                        while j < b.len() && b[j].is_ascii_digit() {
                            j += 1;
                        }
                        i = j;
                    }
                }
                let text = &src[start..i];
                let v: f64 = match text.parse() {
                    Ok(v) => v,
                    Err(_) => return perr(start, format!("bad number '{}'", shorten(text))),
                };
                if !v.is_finite() {
                    return perr(
                        start,
                        format!("number '{}' is too large (not finite)", shorten(text)),
                    );
                }
                out.push((start, Tok::Num(v)));
                continue;
            }
            c if c.is_ascii_alphabetic() => {
                while i < b.len() && b[i].is_ascii_alphanumeric() {
                    i += 1;
                }
                let word = &src[start..i];
                match word {
                    "s" => out.push((start, Tok::S)),
                    "exp" => out.push((start, Tok::Exp)),
                    "inf" | "nan" | "NaN" | "Inf" | "infinity" => {
                        return perr(start, format!("'{word}' is not a finite number"))
                    }
                    _ => {
                        return perr(
                            start,
                            format!(
                                "unknown name '{}' (the variable is 's'; 'exp' is the only \
                                 function)",
                                shorten(word)
                            ),
                        )
                    }
                }
                continue;
            }
            _ => {
                return perr(
                    start,
                    format!(
                        "unexpected character '{}'",
                        src[start..].chars().next().unwrap_or('?')
                    ),
                )
            }
        }
        i += 1;
    }
    Ok(out)
}

/// A rational expression being built: `num / den * exp(-delay s)`.
#[derive(Debug, Clone)]
struct Val {
    num: Vec<Term>,
    den: Vec<Term>,
    delay: f64,
}

/// The most terms a multiplied-out polynomial may have: products of sums with unrelated orders
/// double the count with every factor, so a short input could otherwise ask for billions.
const MAX_TERMS: usize = 1000;

/// The deepest nesting of parentheses, `exp(...)` and signs: the parser recurses on each, and the
/// stack is finite.
const MAX_DEPTH: usize = 100;

fn poly_mul(a: &[Term], b: &[Term], pos: usize) -> Result<Vec<Term>> {
    let mut out: Vec<Term> = Vec::new();
    for x in a {
        for y in b {
            let t = Term::new(x.coef * y.coef, x.order + y.order);
            match out.iter().position(|o| (o.order - t.order).abs() < 1e-12) {
                Some(i) => out[i].coef += t.coef,
                None if out.len() == MAX_TERMS => {
                    return perr(
                        pos,
                        format!("the product has more than {MAX_TERMS} terms in s"),
                    )
                }
                None => out.push(t),
            }
        }
    }
    Ok(out)
}

impl Val {
    fn constant(c: f64) -> Self {
        Self {
            num: vec![Term::new(c, 0.0)],
            den: vec![Term::new(1.0, 0.0)],
            delay: 0.0,
        }
    }
    fn is_poly(&self) -> bool {
        self.delay == 0.0 && self.den.len() == 1 && self.den[0].order == 0.0
    }
    /// Fold a constant denominator into the numerator.
    fn as_poly(&self) -> Option<Vec<Term>> {
        if !self.is_poly() {
            return None;
        }
        let d = self.den[0].coef;
        Some(
            self.num
                .iter()
                .map(|t| Term::new(t.coef / d, t.order))
                .collect(),
        )
    }
    /// `self + sign o`: polynomials term by term; rational expressions over a common
    /// denominator, `a/b + c/d = (a d + c b)/(b d)` (a direct feed-through `D + G(s)`, a
    /// parallel connection). Both must have the same delay (`exp(-tau s)` multiplies a whole
    /// sum); `pos` is where `o` starts, for the error.
    fn add(self, o: Val, sign: f64, pos: usize) -> Result<Val> {
        let o_num: Vec<Term> = o
            .num
            .iter()
            .map(|t| Term::new(sign * t.coef, t.order))
            .collect();
        if let (Some(mut a), Some(_)) = (self.as_poly(), o.as_poly()) {
            let d = o.den[0].coef;
            a.extend(o_num.into_iter().map(|t| Term::new(t.coef / d, t.order)));
            return Ok(Val {
                num: a,
                den: vec![Term::new(1.0, 0.0)],
                delay: 0.0,
            });
        }
        if self.delay != o.delay {
            return perr(
                pos,
                "terms with different delays cannot be added (exp(-tau s) must multiply the \
                 whole model)",
            );
        }
        let mut num = poly_mul(&self.num, &o.den, pos)?;
        for t in poly_mul(&o_num, &self.den, pos)? {
            match num.iter().position(|x| (x.order - t.order).abs() < 1e-12) {
                Some(i) => num[i].coef += t.coef,
                None if num.len() == MAX_TERMS => {
                    return perr(pos, format!("the sum has more than {MAX_TERMS} terms in s"))
                }
                None => num.push(t),
            }
        }
        num.retain(|t| t.coef != 0.0);
        Ok(Val {
            num,
            den: poly_mul(&self.den, &o.den, pos)?,
            delay: self.delay,
        })
    }
    /// `self * o`; `pos` is where `o` starts, for the error.
    fn mul(self, o: Val, pos: usize) -> Result<Val> {
        Ok(Val {
            num: poly_mul(&self.num, &o.num, pos)?,
            den: poly_mul(&self.den, &o.den, pos)?,
            delay: self.delay + o.delay,
        })
    }
    /// `self / o`; `pos` is where `o` starts, for the error.
    fn div(self, o: Val, pos: usize) -> Result<Val> {
        Ok(Val {
            num: poly_mul(&self.num, &o.den, pos)?,
            den: poly_mul(&self.den, &o.num, pos)?,
            delay: self.delay - o.delay,
        })
    }
}

struct Parser<'a> {
    toks: &'a [(usize, Tok)],
    i: usize,
    end: usize,
    /// Current nesting depth (see [`MAX_DEPTH`]).
    depth: usize,
}

impl Parser<'_> {
    fn peek(&self) -> Option<&Tok> {
        self.toks.get(self.i).map(|t| &t.1)
    }
    fn pos(&self) -> usize {
        self.toks.get(self.i).map_or(self.end, |t| t.0)
    }
    fn eat(&mut self, t: &Tok) -> bool {
        if self.peek() == Some(t) {
            self.i += 1;
            true
        } else {
            false
        }
    }
    /// Run `f` one nesting level deeper, or fail past [`MAX_DEPTH`].
    fn nested(&mut self, f: impl FnOnce(&mut Self) -> Result<Val>) -> Result<Val> {
        if self.depth == MAX_DEPTH {
            return perr(
                self.pos(),
                format!("nested more than {MAX_DEPTH} levels deep"),
            );
        }
        self.depth += 1;
        let v = f(self);
        self.depth -= 1;
        v
    }
    fn expr(&mut self) -> Result<Val> {
        self.nested(Self::expr_inner)
    }
    fn expr_inner(&mut self) -> Result<Val> {
        let start = self.pos();
        let mut acc = self.term()?;
        loop {
            let sign = if self.eat(&Tok::Plus) {
                1.0
            } else if self.eat(&Tok::Minus) {
                -1.0
            } else {
                return Ok(acc);
            };
            let pos = self.pos();
            let rhs = self.term()?;
            acc = acc.add(rhs, sign, pos.min(start.max(pos)))?;
        }
    }
    fn term(&mut self) -> Result<Val> {
        let mut acc = self.unary()?;
        loop {
            match self.peek() {
                Some(Tok::Star) => {
                    self.i += 1;
                    let pos = self.pos();
                    acc = acc.mul(self.unary()?, pos)?;
                }
                Some(Tok::Slash) => {
                    self.i += 1;
                    let pos = self.pos();
                    let rhs = self.unary()?;
                    if rhs.num.iter().all(|t| t.coef == 0.0) {
                        return perr(pos, "division by zero");
                    }
                    acc = acc.div(rhs, pos)?;
                }
                // implicit multiplication: "0.0059 s^0.92", "2 (s + 1)", "6.8 exp(-0.01 s)"
                Some(Tok::Num(_) | Tok::S | Tok::LParen | Tok::Exp) => {
                    let pos = self.pos();
                    acc = acc.mul(self.power()?, pos)?;
                }
                _ => return Ok(acc),
            }
        }
    }
    fn unary(&mut self) -> Result<Val> {
        let pos = self.pos();
        if self.eat(&Tok::Minus) {
            let v = self.nested(Self::unary)?;
            return Val::constant(-1.0).mul(v, pos);
        }
        if self.eat(&Tok::Plus) {
            return self.nested(Self::unary);
        }
        self.power()
    }
    /// The exponent after `^`: a number, signed, or in parentheses. Without parentheses a sign
    /// must touch both the `^` and the number (`s^-1`): in `1/(s^ + 1)` or `s^ - 1` the exponent
    /// is missing, and the sign belongs to the sum.
    fn signed_number(&mut self) -> Result<f64> {
        const MISSING: &str = "missing exponent after '^' (write s^a with a number a, e.g. s^0.5, \
                               s^-1 or s^(-1))";
        let pos = self.pos();
        let caret_end = self.toks.get(self.i.wrapping_sub(1)).map_or(0, |t| t.0 + 1);
        let mut sign = 1.0;
        let paren = self.eat(&Tok::LParen);
        let sign_pos = self.pos();
        let signed = if self.eat(&Tok::Minus) {
            sign = -1.0;
            true
        } else {
            self.eat(&Tok::Plus)
        };
        let v = match self.peek() {
            Some(Tok::Num(v)) => *v,
            _ => return perr(pos, MISSING),
        };
        if signed && !paren && (sign_pos != caret_end || self.pos() != sign_pos + 1) {
            return perr(pos, MISSING);
        }
        self.i += 1;
        if paren && !self.eat(&Tok::RParen) {
            return perr(self.pos(), "expected ')'");
        }
        Ok(sign * v)
    }
    fn power(&mut self) -> Result<Val> {
        let pos = self.pos();
        let atom = self.atom()?;
        if !self.eat(&Tok::Caret) {
            return Ok(atom);
        }
        let p = self.signed_number()?;
        // Only a single term (c s^a) can be raised to a real power.
        match atom.as_poly().as_deref() {
            Some([t]) if t.coef > 0.0 || p.fract() == 0.0 => {
                let coef = t.coef.powf(p);
                if !coef.is_finite() {
                    return perr(pos, "power is not finite");
                }
                let order = t.order * p;
                if order < 0.0 {
                    Ok(Val {
                        num: vec![Term::new(1.0, 0.0)],
                        den: vec![Term::new(1.0 / coef, -order)],
                        delay: 0.0,
                    })
                } else {
                    Ok(Val {
                        num: vec![Term::new(coef, order)],
                        den: vec![Term::new(1.0, 0.0)],
                        delay: 0.0,
                    })
                }
            }
            _ => perr(
                pos,
                "only a single term like 's' or '2 s^0.5' can be raised to a power",
            ),
        }
    }
    fn atom(&mut self) -> Result<Val> {
        let pos = self.pos();
        match self.peek().cloned() {
            Some(Tok::Num(v)) => {
                self.i += 1;
                Ok(Val::constant(v))
            }
            Some(Tok::S) => {
                self.i += 1;
                Ok(Val {
                    num: vec![Term::new(1.0, 1.0)],
                    den: vec![Term::new(1.0, 0.0)],
                    delay: 0.0,
                })
            }
            Some(Tok::LParen) => {
                self.i += 1;
                let v = self.expr()?;
                if !self.eat(&Tok::RParen) {
                    return perr(self.pos(), "expected ')'");
                }
                Ok(v)
            }
            Some(Tok::Exp) => {
                self.i += 1;
                if !self.eat(&Tok::LParen) {
                    return perr(self.pos(), "expected '(' after exp");
                }
                let apos = self.pos();
                let arg = self.expr()?;
                if !self.eat(&Tok::RParen) {
                    return perr(self.pos(), "expected ')'");
                }
                match arg.as_poly().as_deref() {
                    Some([t]) if t.order == 1.0 => Ok(Val {
                        num: vec![Term::new(1.0, 0.0)],
                        den: vec![Term::new(1.0, 0.0)],
                        delay: -t.coef,
                    }),
                    Some([]) => Ok(Val::constant(1.0)),
                    _ => perr(apos, "exp() takes a delay term like '-0.001 s'"),
                }
            }
            Some(t) => perr(
                pos,
                format!(
                    "unexpected {} (a number, 's', 'exp' or '(' was expected)",
                    t.describe()
                ),
            ),
            None => perr(pos, "the model ends too early (a term is missing)"),
        }
    }
}

impl FromStr for FracTf {
    type Err = Error;
    /// Parse `6.82/(2.655e-5 s^1.7452 + 0.0059 s^0.92 + 1)`, `exp(-0.001 s)` allowed as a factor.
    ///
    /// # Errors
    /// [`Error::Parse`] with the position for malformed input; the errors of [`FracTf::new`].
    fn from_str(src: &str) -> Result<Self> {
        let toks = lex(src)?;
        if toks.is_empty() {
            return perr(0, "empty model");
        }
        let mut p = Parser {
            toks: &toks,
            i: 0,
            end: src.len(),
            depth: 0,
        };
        let v = p.expr()?;
        if p.i != toks.len() {
            let what = p
                .peek()
                .map_or(String::new(), |t| format!(" ({})", t.describe()));
            return perr(p.pos(), format!("unexpected text after the model{what}"));
        }
        // Normalise so that the denominator's order-zero term (or its lowest term) is the
        // scale the user wrote: keep coefficients as given.
        let mut g = FracTf::new(v.num, v.den, v.delay)?;
        // A series connection as people write it (`F1 * F2`, `N/((D1)(D2))`): its factors are
        // kept for the simulators (see `FracTf::with_factors`), not shown.
        if let Some(fs) = written_factors(&toks, src.len()) {
            if let Ok(h) = g.clone().with_factors(fs) {
                g = FracTf {
                    show_factors: false,
                    direct: None,
                    ..h
                };
            }
        }
        Ok(g)
    }
}

type Toks<'a> = &'a [(usize, Tok)];

/// `toks` cut at the tokens outside parentheses for which `cut(previous, this)` holds (the cut
/// token itself dropped when `drop` holds for it).
fn split_top<'a>(
    toks: Toks<'a>,
    cut: impl Fn(Option<&Tok>, &Tok) -> bool,
    drop: impl Fn(&Tok) -> bool,
) -> Vec<Toks<'a>> {
    let (mut pieces, mut depth, mut from) = (vec![], 0i32, 0);
    for (k, (_, t)) in toks.iter().enumerate() {
        if depth == 0 && k > 0 && cut(toks.get(k - 1).map(|p| &p.1), t) {
            pieces.push(&toks[from..k]);
            from = if drop(t) { k + 1 } else { k };
        }
        match t {
            Tok::LParen => depth += 1,
            Tok::RParen => depth -= 1,
            _ => {}
        }
    }
    pieces.push(&toks[from..]);
    pieces
}

/// The groups a product is written as: `(A)(B)`, `(A) * (B)`, either inside one more pair of
/// parentheses; a text that is no such product is one group.
fn product_groups(toks: Toks<'_>) -> Vec<Toks<'_>> {
    // one pair of parentheses around the whole: the first closes at the last token
    let mut depth = 0i32;
    let wrapped = matches!(toks.first(), Some((_, Tok::LParen)))
        && toks.iter().enumerate().all(|(k, (_, t))| {
            match t {
                Tok::LParen => depth += 1,
                Tok::RParen => depth -= 1,
                _ => {}
            }
            depth > 0 || k == toks.len() - 1
        });
    let inner = if wrapped {
        &toks[1..toks.len() - 1]
    } else {
        toks
    };
    let groups = split_top(
        inner,
        |prev, t| *t == Tok::Star || (prev == Some(&Tok::RParen) && *t == Tok::LParen),
        |t| *t == Tok::Star,
    );
    if groups.len() >= 2 {
        groups
    } else {
        vec![toks]
    }
}

/// The series factors the text is written as, each proper: a product at the top of the text
/// (`F1 * F2`, each factor as written), or a quotient whose denominator is a product
/// (`N/((D1)(D2))`, `N/(D1)/(D2)`): one factor per denominator group, the numerator's groups
/// each joined to the remaining factor of highest denominator order that stays proper with it
/// (so `6.82/((a2 s^1.75 + a1 s^0.92 + 1)(m s^2 + c s + 1))` is simulated as its two stores in
/// series rather than as one nine-term denominator). None when the text is no such product.
fn written_factors(toks: Toks<'_>, end: usize) -> Option<Vec<FracTf>> {
    let parse = |ts: Toks<'_>| -> Option<Val> {
        let mut q = Parser {
            toks: ts,
            i: 0,
            end,
            depth: 0,
        };
        let v = q.expr().ok()?;
        (q.i == ts.len()).then_some(v)
    };
    let tf = |v: Val| FracTf::new(v.num, v.den, v.delay.max(0.0)).ok();
    let top = split_top(toks, |_, t| *t == Tok::Star, |_| true);
    if top.len() >= 2 {
        return top.into_iter().map(|ts| tf(parse(ts)?)).collect();
    }
    let quotient = split_top(toks, |_, t| *t == Tok::Slash, |_| true);
    let (num, dens) = quotient.split_first()?;
    let den_groups: Vec<Toks<'_>> = dens.iter().flat_map(|d| product_groups(d)).collect();
    if den_groups.len() < 2 {
        return None;
    }
    let mut factors: Vec<FracTf> = den_groups
        .into_iter()
        .map(|d| {
            let v = parse(d)?;
            tf(Val {
                num: v.den,
                den: v.num,
                delay: 0.0,
            })
        })
        .collect::<Option<_>>()?;
    let mut nums: Vec<FracTf> = product_groups(num)
        .into_iter()
        .map(|n| tf(parse(n)?))
        .collect::<Option<_>>()?;
    nums.sort_by(|a, b| {
        (b.num_order() - b.den_order()).total_cmp(&(a.num_order() - a.den_order()))
    });
    for n in nums {
        let k = (0..factors.len())
            .filter(|&k| {
                factors[k].num_order() + n.num_order()
                    <= factors[k].den_order() + n.den_order() + 1e-12
            })
            .max_by(|&a, &b| factors[a].den_order().total_cmp(&factors[b].den_order()))?;
        let f = &factors[k];
        let joined = Val {
            num: poly_mul(&f.num, &n.num, 0).ok()?,
            den: poly_mul(&f.den, &n.den, 0).ok()?,
            delay: 0.0,
        };
        factors[k] = tf(joined)?;
    }
    Some(factors)
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    /// A direct feed-through and a parallel connection are written as sums: each is the sum of
    /// its parts' responses (evaluated here term by term, not by the parser's fraction).
    #[test]
    fn sums_of_transfer_functions_are_one_fraction() {
        let part = |terms: &[(f64, f64)], w: f64| -> Complex64 {
            terms.iter().map(|&(c, o)| c * jw_pow(w, o)).sum()
        };
        let ft: FracTf = "0.3 + 2/(0.1 s^0.8 + 1)".parse().unwrap();
        let par: FracTf = "2/(s + 1) - 3/(0.5 s^1.5 + 2)".parse().unwrap();
        for w in [1e-2, 0.7, 3.0, 50.0, 1e4] {
            let want = 0.3 + 2.0 / part(&[(0.1, 0.8), (1.0, 0.0)], w);
            assert_relative_eq!(ft.freq_response(w).re, want.re, max_relative = 1e-12);
            assert_relative_eq!(ft.freq_response(w).im, want.im, epsilon = 1e-12);
            let want =
                2.0 / part(&[(1.0, 1.0), (1.0, 0.0)], w) - 3.0 / part(&[(0.5, 1.5), (2.0, 0.0)], w);
            assert_relative_eq!((par.freq_response(w) - want).norm(), 0.0, epsilon = 1e-12);
        }
        // the feed-through is the high-frequency gain; it reads back as one fraction
        assert_relative_eq!(ft.freq_response(1e12).re, 0.3, max_relative = 1e-6);
        let back: FracTf = ft.to_string().parse().unwrap();
        assert_relative_eq!(
            (back.freq_response(3.0) - ft.freq_response(3.0)).norm(),
            0.0,
            epsilon = 1e-12
        );
        // a common delay factors out; different delays do not add
        let d: FracTf = "exp(-0.1 s)/(s + 1) + exp(-0.1 s)/(s + 2)".parse().unwrap();
        assert_eq!(d.delay, 0.1);
        let e = "1 + exp(-0.1 s)/(s + 1)".parse::<FracTf>().unwrap_err();
        assert!(e.to_string().contains("different delays"), "{e}");
        // polynomials still add term by term
        let p: FracTf = "(s^0.5 + 2 + 3 s)/(s^2 + 1)".parse().unwrap();
        assert_eq!(p.num.len(), 3);
    }

    #[test]
    fn parses_the_paper_models() {
        let g: FracTf = "6.82/(0.00002655 s^1.7452 + 0.0059 s^0.92 + 1)"
            .parse()
            .unwrap();
        assert_eq!(g.num, vec![Term::new(6.82, 0.0)]);
        assert_eq!(g.den.len(), 3);
        assert_relative_eq!(g.den[0].coef, 2.655e-5);
        assert_relative_eq!(g.den[0].order, 1.7452);
        assert_relative_eq!(g.den[1].coef, 0.0059);
        assert_relative_eq!(g.den[2].coef, 1.0);
        let d: FracTf = "exp(-0.001 s) * 6.77/(2.8e-5s^1.78+6.4e-3*s^0.89+1)"
            .parse()
            .unwrap();
        assert_relative_eq!(d.delay, 0.001);
        assert_relative_eq!(d.den[0].coef, 2.8e-5);
    }

    #[test]
    fn display_round_trips() {
        for src in [
            "6.82/(2.655e-5 s^1.7452 + 0.0059 s^0.92 + 1)",
            "(2 s^0.5 + 1)/(s^1.5 - 0.3 s + 4) exp(-0.02 s)",
            "1/(s + 1)",
        ] {
            let g: FracTf = src.parse().unwrap();
            let again: FracTf = g.to_string().parse().unwrap();
            assert_eq!(g, again, "{src} -> {g}");
        }
    }

    #[test]
    fn products_and_quotients_multiply_out() {
        let g: FracTf = "2/((s^0.5 + 1)(s^0.5 + 2))".parse().unwrap();
        // (s^.5+1)(s^.5+2) = s + 3 s^.5 + 2
        assert_eq!(
            g.den,
            vec![
                Term::new(1.0, 1.0),
                Term::new(3.0, 0.5),
                Term::new(2.0, 0.0)
            ]
        );
        assert_relative_eq!(g.dc_gain(), 1.0);
    }

    #[test]
    fn bad_models_are_errors() {
        for bad in [
            "",
            "6.8/(",
            "6.8/(s^ * 1)",
            "6.8/(x + 1)",
            "6.8/0",
            "1/(0 s + 0)",
            "1e400/(s+1)",
            "nan/(s+1)",
            "1 + exp(-0.1 s)/(s+1)",
            "exp(s^2)/(s+1)",
            "1/(s+1))",
            "exp(0.1 s)/(s+1)",
            "1/(s^30+1)",
            "(1)",
            "s^0.5",
        ] {
            let r: Result<FracTf> = bad.parse();
            // "(1)" and "s^0.5" are valid (constant gain, a differentiator): skip them.
            if bad == "(1)" || bad == "s^0.5" {
                assert!(r.is_ok(), "{bad}");
                continue;
            }
            assert!(r.is_err(), "{bad} parsed as {:?}", r.unwrap());
        }
    }

    #[test]
    fn missing_exponents_and_messages_in_words() {
        // a missing exponent was read as a sign: 1/(s^ + 1) simulated as 1/s, 1/(s^ - 1) as s
        for bad in [
            "1/(s^ + 1)",
            "1/(s^ - 1)",
            "1/(s^- 1)",
            "1/(s ^ -1 + 1)",
            "1/(s^)",
            "s^",
        ] {
            let e = bad.parse::<FracTf>().unwrap_err().to_string();
            assert!(e.contains("missing exponent after '^'"), "{bad}: {e}");
        }
        // but a sign that touches both is an exponent, and parentheses are explicit
        for (ok, order) in [
            ("1/s^-1", 0.0),
            ("1/(s^(+ 2) + 1)", 2.0),
            ("1/(s^ 2 + 1)", 2.0),
        ] {
            let g: FracTf = ok.parse().unwrap();
            assert!(g.num_order() == 1.0 || g.den_order() == order, "{ok}: {g}");
        }
        let e = "1/(s**2 + 1)".parse::<FracTf>().unwrap_err().to_string();
        assert!(
            e.contains("'**' is not supported: write powers as s^a"),
            "{e}"
        );
        let e = "1/(s + )".parse::<FracTf>().unwrap_err().to_string();
        assert!(e.contains("unexpected ')'") && !e.contains("RParen"), "{e}");
        let e = "1/(s + 1) 2)".parse::<FracTf>().unwrap_err().to_string();
        assert!(e.contains("')'") && !e.contains("RParen"), "{e}");
        // a 300-digit number is quoted short
        let e = format!("{}/(s+1)", "9".repeat(400))
            .parse::<FracTf>()
            .unwrap_err()
            .to_string();
        assert!(e.contains("(400 characters)") && e.len() < 150, "{e}");
    }

    #[test]
    fn improper_models_are_refused_for_simulation() {
        let g: FracTf = "s^3/(s+1)".parse().unwrap();
        let e = g.check_proper().unwrap_err().to_string();
        assert!(
            e.contains("improper") && e.contains("order 3 > denominator order 1"),
            "{e}"
        );
        assert!("s^0.5".parse::<FracTf>().unwrap().check_proper().is_err());
        for ok in [
            "(s + 1)/(s + 2)",
            "6.8/(2e-5 s^1.75 + 0.006 s^0.9 + 1)",
            "1",
        ] {
            assert!(ok.parse::<FracTf>().unwrap().check_proper().is_ok(), "{ok}");
        }
    }

    #[test]
    fn deep_nesting_and_huge_products_are_errors_not_crashes() {
        // 20000 parentheses overflowed the stack (an abort, not even a panic).
        let deep = format!("{}1{}", "(".repeat(20_000), ")".repeat(20_000));
        let err = deep.parse::<FracTf>().unwrap_err().to_string();
        assert!(err.contains("nested more than 100 levels"), "{err}");
        for deep in [
            format!("1{}", "(1".repeat(20_000)),
            format!("1*{}1", "-".repeat(20_000)),
            format!("{}1/(s+1){}", "exp(-s)*(".repeat(5_000), ")".repeat(5_000)),
        ] {
            assert!(deep.parse::<FracTf>().is_err());
        }
        // but 100 levels are fine
        let ok = format!("{}1/(s+1){}", "(".repeat(98), ")".repeat(98));
        assert_eq!(ok.parse::<FracTf>().unwrap().dc_gain(), 1.0);
        // 30 factors with unrelated orders: 2^30 terms, which took forever.
        let product: String = (1..=30)
            .map(|k| format!("(s^{} + 1)", 0.5 / f64::from(k).sqrt()))
            .collect();
        let err = format!("1/{product}").parse::<FracTf>().unwrap_err();
        assert!(err.to_string().contains("more than 1000 terms"), "{err}");
    }

    #[test]
    fn frequency_response_of_first_order() {
        let g: FracTf = "1/(0.1 s + 1)".parse().unwrap();
        let h = g.freq_response(10.0);
        assert_relative_eq!(h.norm(), 1.0 / 2f64.sqrt(), epsilon = 1e-14);
        assert_relative_eq!(h.arg(), -std::f64::consts::FRAC_PI_4, epsilon = 1e-14);
        let d = g.clone().with_delay(0.01).unwrap().freq_response(10.0);
        assert_relative_eq!(d.arg(), -std::f64::consts::FRAC_PI_4 - 0.1, epsilon = 1e-14);
    }

    #[test]
    fn dc_gain_of_integrator_is_infinite() {
        let g: FracTf = "1/s^0.5".parse().unwrap();
        assert!(g.dc_gain().is_infinite());
    }
}
