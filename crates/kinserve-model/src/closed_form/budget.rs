//! The work budget of a closed form: what multiplying out, simplifying and
//! printing may cost before the closed form is refused, and the refusal.
//!
//! Work is counted in *atom operations*: a product of two terms costs twice
//! the atoms of both plus one, a simplification pass costs `4 + 4·len + len²`
//! per term of `len` atoms (it tries every pair of factors), and printing
//! costs 32 operations per atom and per term (three formats and the
//! common-factor search). The weights make one operation about the same CPU
//! time in each part (measured, see [`MAX_WORK`]). Every step is charged *before* it runs, so a refusal comes after
//! at most [`MAX_WORK`] operations and never after a long step.
//!
//! Owns the limits and the error they give; depends on `error` only.

use crate::error::ModelError;

/// Most atom operations one closed form may cost (product, simplification
/// and printing together). Measured with
/// `cargo run --release -p kinserve-model --example closed_form_cost` (release
/// build, 2 shared cores, best of 5): 13–26 ns per operation, so a closed
/// form at the limit costs about 50–100 ms of CPU. The largest served there:
/// 7 twisted revolute rows, 2,451,142 operations, 33 ms, a 3.8 MB answer; the
/// slowest refusal 63 ms (a ±90° snake); the issue-22 attack model (8
/// twisted + 248 identity rows) refused in 28 ms; every shipped arm under
/// 50,000 operations and 1 ms.
pub(crate) const MAX_WORK: u64 = 4_000_000;

/// Most terms the product may hold (all entries together) after any factor;
/// longer closed forms are refused instead of being printed.
pub(crate) const MAX_TERMS: usize = 20_000;

/// Why a closed form was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Exceeded {
    /// The next step would take the work past [`MAX_WORK`]; `needed` is the
    /// work done so far plus that step's.
    Work { needed: u64 },
    /// The product holds `terms` terms after a factor, more than [`MAX_TERMS`].
    Terms { terms: usize },
    /// An integer coefficient left the range of `i64`.
    Coefficient,
}

/// Work done so far against a limit.
#[derive(Clone, Debug)]
pub(crate) struct Budget {
    used: u64,
    limit: u64,
}

impl Budget {
    /// A budget of `limit` atom operations.
    pub(crate) fn new(limit: u64) -> Budget {
        Budget { used: 0, limit }
    }

    /// Takes `units` from the budget, or fails without taking them.
    pub(crate) fn charge(&mut self, units: u64) -> Result<(), Exceeded> {
        let needed = self.used.saturating_add(units);
        if needed > self.limit {
            return Err(Exceeded::Work { needed });
        }
        self.used = needed;
        Ok(())
    }

    /// Atom operations charged so far.
    pub(crate) fn used(&self) -> u64 {
        self.used
    }
}

impl Exceeded {
    /// The error the client sees: too large, on `links`, with the limit and what to do.
    pub(crate) fn into_error(self) -> ModelError {
        const ADVICE: &str = "long chains of twisted axes (alpha not a multiple of 90°) grow \
            exponentially; use fewer such rows, or ask for numbers instead (forward kinematics, \
            link transforms)";
        let why = match self {
            Exceeded::Work { needed } => format!(
                "the closed form of this table needs more than {MAX_WORK} operations to multiply \
                 out and print (at least {needed})"
            ),
            Exceeded::Terms { terms } => format!(
                "the closed form of this table has more than {MAX_TERMS} terms ({terms} after a \
                 partial product)"
            ),
            Exceeded::Coefficient => {
                "the closed form of this table has a coefficient beyond 64-bit integers".to_string()
            }
        };
        ModelError::too_large("links", format!("{why}; too large to print: {ADVICE}"))
    }
}
