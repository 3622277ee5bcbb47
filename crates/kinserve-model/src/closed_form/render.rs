//! Printing symbolic matrices three ways: `text` (the documented grammar,
//! one expression string per entry), LaTeX as the course notes print it
//! (`c_{1} c_{23}`, `a_{2}`) and presentation MathML.
//!
//! Owns names and layout only: the order of terms (constant terms first, then
//! by factors), a common factor pulled out of an entry (`c1*(a2*c2 + a3*c23)`).
//! Must not depend on how the matrices were built (`build`).

use super::build::Matrix;
use super::poly::{Angle, Atom, Length, Monomial, Poly, Trig};

/// Work of printing one atom or one term, in atom operations: each is named,
/// formatted and copied in three formats, and the common factor is searched
/// three times. Measured: printing costs about eight times a term product per
/// atom (see `budget`).
pub(crate) const PRINT_COST: u64 = 32;

/// Output format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Format {
    Text,
    Latex,
    MathMl,
}

/// A format plus the naming rule for joint sets.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Style {
    pub(crate) format: Format,
    /// Separate row numbers in `cI`/`sI` (`c9_10`): tables of 10 rows or more.
    pub(crate) separated: bool,
}

/// What printing `m` in the three formats costs, in the atom operations of
/// `budget`: [`PRINT_COST`] per atom and per term.
pub(crate) fn cost(m: &Matrix) -> u64 {
    m.iter()
        .flatten()
        .map(|p| PRINT_COST * (p.atoms() + p.len()) as u64)
        .fold(0, u64::saturating_add)
}

impl Style {
    /// One expression per entry (the `text` field).
    pub(crate) fn text_matrix(&self, m: &Matrix) -> Vec<Vec<String>> {
        m.iter()
            .map(|row| row.iter().map(|p| self.entry(p)).collect())
            .collect()
    }

    /// The whole matrix as one LaTeX or MathML string.
    pub(crate) fn matrix(&self, m: &Matrix) -> String {
        let rows: Vec<Vec<String>> = m
            .iter()
            .map(|row| row.iter().map(|p| self.entry(p)).collect())
            .collect();
        match self.format {
            Format::Text => rows
                .iter()
                .map(|r| format!("[{}]", r.join(", ")))
                .collect::<Vec<_>>()
                .join("\n"),
            Format::Latex => {
                let body: Vec<String> = rows.iter().map(|r| r.join(" & ")).collect();
                format!(
                    "\\begin{{bmatrix}} {} \\end{{bmatrix}}",
                    body.join(" \\\\ ")
                )
            }
            Format::MathMl => {
                let body: String = rows
                    .iter()
                    .map(|r| {
                        let cells: String = r.iter().map(|c| format!("<mtd>{c}</mtd>")).collect();
                        format!("<mtr>{cells}</mtr>")
                    })
                    .collect();
                format!(
                    "<math xmlns=\"http://www.w3.org/1998/Math/MathML\" display=\"block\"><mrow><mo>[</mo><mtable>{body}</mtable><mo>]</mo></mrow></math>"
                )
            }
        }
    }

    /// One entry: a sum, with a factor common to every term pulled out.
    pub(crate) fn entry(&self, p: &Poly) -> String {
        let out = match factor(p) {
            Some((negative, common, inner)) => {
                let mut parts: Vec<String> = common.iter().map(|a| self.atom(a)).collect();
                parts.push(self.parens(&self.sum(&inner)));
                let product = self.product(&parts);
                if negative {
                    format!("{}{product}", self.minus())
                } else {
                    product
                }
            }
            None => self.sum(p),
        };
        match self.format {
            Format::MathMl => format!("<mrow>{out}</mrow>"),
            _ => out,
        }
    }

    /// A sum of terms in print order; `0` when empty.
    fn sum(&self, p: &Poly) -> String {
        let mut terms: Vec<(&Monomial, i64)> = p.terms().collect();
        terms.sort_by_key(|(m, _)| (variables(m), *m));
        if terms.is_empty() {
            return self.number(0);
        }
        let mut out = String::new();
        for (n, (m, k)) in terms.into_iter().enumerate() {
            let body = self.term(m, k.unsigned_abs());
            out += &match (n, k < 0) {
                (0, false) => body,
                (0, true) => format!("{}{body}", self.minus()),
                (_, false) => format!("{}{body}", self.infix("+")),
                (_, true) => format!("{}{body}", self.infix("-")),
            };
        }
        out
    }

    /// `|k| · m` without its sign.
    fn term(&self, m: &Monomial, k: u64) -> String {
        let mut parts = Vec::with_capacity(m.len() + 1);
        if k != 1 || m.is_empty() {
            parts.push(self.number(k));
        }
        parts.extend(m.iter().map(|a| self.atom(a)));
        self.product(&parts)
    }

    fn product(&self, parts: &[String]) -> String {
        parts.join(match self.format {
            Format::Text => "*",
            Format::Latex => " ",
            Format::MathMl => "<mo>&#x2062;</mo>",
        })
    }

    fn number(&self, k: u64) -> String {
        match self.format {
            Format::MathMl => format!("<mn>{k}</mn>"),
            _ => k.to_string(),
        }
    }

    fn minus(&self) -> &'static str {
        match self.format {
            Format::MathMl => "<mo>&#x2212;</mo>",
            _ => "-",
        }
    }

    fn infix(&self, op: &str) -> String {
        match (self.format, op) {
            (Format::MathMl, "-") => "<mo>&#x2212;</mo>".into(),
            (Format::MathMl, _) => format!("<mo>{op}</mo>"),
            _ => format!(" {op} "),
        }
    }

    fn parens(&self, s: &str) -> String {
        match self.format {
            Format::Text => format!("({s})"),
            Format::Latex => format!("\\left({s}\\right)"),
            Format::MathMl => format!("<mrow><mo>(</mo>{s}<mo>)</mo></mrow>"),
        }
    }

    /// An atom's name in this format.
    pub(crate) fn atom(&self, a: &Atom) -> String {
        match a {
            Atom::Length(Length::A, i) => self.indexed("a", &[*i]),
            Atom::Length(Length::D, i) | Atom::Slide(i) => self.indexed("d", &[*i]),
            Atom::Joint(rows, t) => self.indexed(trig_letter(*t), rows),
            Atom::Const(t, angle, i) => self.constant_trig(*t, *angle, *i),
        }
    }

    /// `c23`, `c_{23}`, `c9_10`, `c_{9,10}`, or the MathML of the same.
    fn indexed(&self, letter: &str, rows: &[u16]) -> String {
        let nums: Vec<String> = rows.iter().map(u16::to_string).collect();
        match self.format {
            Format::Text => format!(
                "{letter}{}",
                nums.join(if self.separated { "_" } else { "" })
            ),
            Format::Latex => format!(
                "{letter}_{{{}}}",
                nums.join(if self.separated { "," } else { "" })
            ),
            Format::MathMl => {
                let sub = if self.separated && nums.len() > 1 {
                    let inner: Vec<String> = nums.iter().map(|n| format!("<mn>{n}</mn>")).collect();
                    format!("<mrow>{}</mrow>", inner.join("<mo>,</mo>"))
                } else {
                    format!("<mn>{}</mn>", nums.concat())
                };
                format!("<msub><mi>{letter}</mi>{sub}</msub>")
            }
        }
    }

    /// `cos_alpha3`, `\cos\alpha_{3}`, or MathML `cos α₃`.
    fn constant_trig(&self, t: Trig, angle: Angle, i: u16) -> String {
        let f = match t {
            Trig::Cos => "cos",
            Trig::Sin => "sin",
        };
        let (name, latex, greek) = match angle {
            Angle::Alpha => ("alpha", "\\alpha", "&#x3B1;"),
            Angle::Theta => ("theta", "\\theta", "&#x3B8;"),
        };
        match self.format {
            Format::Text => format!("{f}_{name}{i}"),
            Format::Latex => format!("\\{f}{latex}_{{{i}}}"),
            Format::MathMl => format!(
                "<mrow><mi>{f}</mi><mo>&#x2061;</mo><msub><mi>{greek}</mi><mn>{i}</mn></msub></mrow>"
            ),
        }
    }
}

fn trig_letter(t: Trig) -> &'static str {
    match t {
        Trig::Cos => "c",
        Trig::Sin => "s",
    }
}

/// Factors that vary with the joints (`cI`, `sI`, prismatic `dI`).
fn variables(m: &Monomial) -> usize {
    m.iter()
        .filter(|a| matches!(a, Atom::Joint(..) | Atom::Slide(_)))
        .count()
}

/// `(negative, common, inner)` with `p = ±common·inner` when `p` has two or
/// more terms sharing at least one factor; the sign is pulled out when every
/// term is negative.
fn factor(p: &Poly) -> Option<(bool, Monomial, Poly)> {
    if p.len() < 2 {
        return None;
    }
    let mut terms = p.terms();
    let (first, _) = terms.next()?;
    let mut common: Monomial = first.clone();
    for (m, _) in terms {
        common = intersect(&common, m);
    }
    if common.is_empty() {
        return None;
    }
    let negative = p.terms().all(|(_, k)| k < 0);
    let mut inner = Poly::default();
    for (m, k) in p.terms() {
        // On a coefficient past i64 (none in practice) the entry prints unfactored.
        let k = if negative { k.checked_neg()? } else { k };
        inner.add_term(remove(m, &common), k).ok()?;
    }
    Some((negative, common, inner))
}

/// Multiset intersection of two sorted monomials.
fn intersect(a: &[Atom], b: &[Atom]) -> Monomial {
    let (mut i, mut j, mut out) = (0, 0, Vec::new());
    while i < a.len() && j < b.len() {
        match a[i].cmp(&b[j]) {
            std::cmp::Ordering::Less => i += 1,
            std::cmp::Ordering::Greater => j += 1,
            std::cmp::Ordering::Equal => {
                out.push(a[i].clone());
                i += 1;
                j += 1;
            }
        }
    }
    out
}

/// `m` without one copy of each factor of `common` (which divides it).
fn remove(m: &[Atom], common: &[Atom]) -> Monomial {
    let mut out = m.to_vec();
    for a in common {
        if let Some(p) = out.iter().position(|x| x == a) {
            out.remove(p);
        }
    }
    out
}
