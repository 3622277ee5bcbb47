//! Closed-form forward kinematics in the course's notation: every link matrix
//! `A_i` and their product `⁰Tₙ` multiplied out symbolically and simplified as
//! the notes do by hand (zero terms dropped, ±1 folded, `sin² + cos² = 1`,
//! angle sums `c23 = cos(θ2 + θ3)` over runs of parallel revolute axes).
//!
//! Owns the [`ClosedForm`] of a validated [`Robot`] and its three renderings.
//! The term representation is in `poly`, the DH-to-symbol step in `build`, the
//! printing in `render`, the work limit in `budget`. Depends on `kinserve-kinematics` (the table) and
//! serde; must not depend on any server crate.
//!
//! # The `text` grammar
//!
//! ```text
//! expr   = ["-"] term { ("+" | "-") term }
//! term   = factor { ("*" | "/") factor }
//! factor = number | identifier | "(" expr ")"
//! ```
//!
//! Identifiers (row numbers `j` are 1-based DH rows; tables with 10 or more
//! rows separate them with `_`, as in `c9_10`):
//! - `cI`, `sI`: cosine and sine of the sum of θ_j over the rows in `I`
//!   (`c1`, `c23`, `s234`), θ_j = joint value + the row's `theta` offset;
//! - `dI` of a prismatic row: its variable, joint value + the row's `d` offset;
//! - every other identifier is a constant whose value is in `symbols`:
//!   `aI`, `dI` (lengths, in the model's length unit; in the modified
//!   convention row `i` holds `a{i-1}` as Craig writes it), and
//!   `cos_alphaI`, `sin_alphaI`, `cos_thetaI`, `sin_thetaI` (unitless) for
//!   constant angles that are not multiples of 90° (those fold to 0 or ±1).
//!
//! kinserve prints only `+ - *` and parentheses; `/` is part of the grammar
//! for clients that substitute their own expressions.

mod budget;
mod build;
mod poly;
mod render;

use std::collections::BTreeMap;

use kinserve_kinematics::JointKind;
use serde::Serialize;

#[cfg(doc)]
use crate::error::ModelError;
use crate::error::Result;
use crate::robot::Robot;
use crate::spec::{ConventionSpec, JointType, LengthUnit};
use budget::{Budget, Exceeded};
use render::{Format, Style};

/// A matrix in the three renderings.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct SymbolicMatrix {
    /// 4×4 row-major expression strings in the documented grammar (the last row is `0, 0, 0, 1`).
    pub text: Vec<Vec<String>>,
    /// LaTeX `bmatrix`, as the course notes print it (`c_{1} c_{23}`, `a_{2}`).
    pub latex: String,
    /// Presentation MathML (`<math display="block">`).
    pub mathml: String,
}

/// A joint variable of the closed form.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct JointVariable {
    /// `theta{j}` (revolute, appears through `cI`/`sI`) or `d{j}` (prismatic).
    pub name: String,
    /// 1-based DH row.
    pub row: usize,
    /// The joint's name in the model.
    pub joint: String,
    /// Revolute or prismatic.
    pub kind: JointType,
    /// The row's offset added to the joint value: rad (revolute) or the model's length unit (prismatic).
    pub offset: f64,
}

/// Closed-form forward kinematics of a robot's DH table.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct ClosedForm {
    /// Robot name.
    pub robot: String,
    /// DH convention of the table (and so of every `A_i`).
    pub convention: ConventionSpec,
    /// Unit of every length symbol, `base` and `tool`.
    pub length_unit: LengthUnit,
    /// The joint variables, in table order.
    pub variables: Vec<JointVariable>,
    /// Value of every constant identifier (lengths in `length_unit`, cos/sin unitless).
    pub symbols: BTreeMap<String, f64>,
    /// `A_1 … A_n`: the matrix of DH row `i + 1` at index `i`.
    pub link_transforms: Vec<SymbolicMatrix>,
    /// `⁰Tₙ = A_1 ⋯ A_n`: the DH rows only; FK is `base · ⁰Tₙ · tool`.
    pub transform: SymbolicMatrix,
    /// The model's base transform, numbers (4×4 row-major).
    pub base: [[f64; 4]; 4],
    /// The model's tool transform, numbers (4×4 row-major); the key is
    /// absent when the model has none (as `tool` is absent from the gRPC
    /// `GetClosedFormResponse`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tool: Option<[[f64; 4]; 4]>,
}

impl ClosedForm {
    /// Most work one closed form may cost, in atom operations (a product of
    /// two terms costs twice the atoms of both plus one; a simplification
    /// pass `4 + 4·len + len²` per term of `len` atoms; printing 32 per atom
    /// and per term): 4,000,000, about 50–100 ms of CPU at the limit
    /// (release build; 13–26 ns per operation measured by
    /// `cargo run --release -p kinserve-model --example closed_form_cost`).
    pub const MAX_WORK: u64 = budget::MAX_WORK;
    /// Most terms the product may hold (all entries together) after any factor.
    pub const MAX_TERMS: usize = budget::MAX_TERMS;

    /// The closed form of `robot`. Fails with [`ModelError::TooLarge`] on
    /// `links` when it would cost more than [`ClosedForm::MAX_WORK`] or hold
    /// more than [`ClosedForm::MAX_TERMS`] terms (long chains with twisted
    /// axes grow exponentially and print nothing useful); it fails before the
    /// step that would pass the limit, so a refusal costs at most the limit.
    /// Identity rows cost nothing, and a run of fixed rows is multiplied into
    /// the product once.
    pub fn of(robot: &Robot) -> Result<ClosedForm> {
        let chain = robot.chain();
        let rows: Vec<_> = chain.dh_rows().collect();
        let (built, product, _) = expand(robot)?;
        let separated = rows.len() >= 10;
        let style = |format| Style { format, separated };
        let render = |m: &build::Matrix| SymbolicMatrix {
            text: style(Format::Text).text_matrix(m),
            latex: style(Format::Latex).matrix(m),
            mathml: style(Format::MathMl).matrix(m),
        };
        let symbols = built
            .values
            .iter()
            .map(|(atom, v)| (style(Format::Text).atom(atom), *v))
            .collect();
        Ok(ClosedForm {
            robot: robot.name().to_string(),
            convention: robot.spec().convention,
            length_unit: robot.length_unit(),
            variables: variables(robot, &rows),
            symbols,
            link_transforms: built.links.iter().map(render).collect(),
            transform: render(&product),
            base: chain.base().matrix(),
            tool: chain.tool().map(|t| t.matrix()),
        })
    }

    /// Whether [`ClosedForm::of`] would succeed, without printing: the work it
    /// costs in atom operations, or the same [`ModelError::TooLarge`]. Exact
    /// (it multiplies out as `of` does and charges the printing it predicts),
    /// and bounded by [`ClosedForm::MAX_WORK`] like `of`; it skips only the
    /// printing, about three quarters of the time of a large served form
    /// (release: under 0.4 ms for every shipped arm, 8 ms for the largest
    /// served form, at most the time of a refusal, ≤ ~65 ms, when it fails).
    pub fn check(robot: &Robot) -> Result<u64> {
        expand(robot).map(|(_, _, work)| work)
    }
}

/// The link matrices and their product of `robot`, within the work budget
/// (printing both charged too), and the work used.
fn expand(robot: &Robot) -> Result<(build::Built, build::Matrix, u64)> {
    let chain = robot.chain();
    let rows: Vec<_> = chain.dh_rows().collect();
    let mut budget = Budget::new(budget::MAX_WORK);
    let expanded = build::build(chain.convention(), &rows).and_then(|built| {
        let product = build::product(&built, &mut budget)?;
        let printing = built
            .links
            .iter()
            .chain([&product])
            .map(render::cost)
            .fold(0, u64::saturating_add);
        budget.charge(printing)?;
        Ok((built, product))
    });
    let (built, product) = expanded.map_err(Exceeded::into_error)?;
    Ok((built, product, budget.used()))
}

fn variables(robot: &Robot, rows: &[kinserve_kinematics::DhRow]) -> Vec<JointVariable> {
    let movable = rows
        .iter()
        .enumerate()
        .filter(|(_, r)| r.kind != JointKind::Fixed);
    movable
        .zip(robot.joints())
        .map(|((i, r), j)| {
            let (prefix, kind, offset) = match r.kind {
                JointKind::Prismatic => ("d", JointType::Prismatic, r.d),
                _ => ("theta", JointType::Revolute, r.theta),
            };
            JointVariable {
                name: format!("{prefix}{}", i + 1),
                row: i + 1,
                joint: j.name.clone(),
                kind,
                offset,
            }
        })
        .collect()
}
