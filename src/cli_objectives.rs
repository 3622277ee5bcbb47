//! The command-line form of the IK objectives shared by `kinserve ik`:
//! `--posture`, `--posture-weights`, `--axis-tolerance AXIS=VALUE` and
//! `--free-axis AXIS`, parsed into the model's request fields.
//!
//! Units as in the request: posture in the answer's angle unit (`--deg`),
//! axis tolerances in the robot's length unit (x, y, z) and rad (rx, ry,
//! rz). Depends on clap and the model's objective types only; must not
//! depend on the server.

use clap::Args;
use kinserve_model::{AxisTolerancesSpec, PoseAxis, PostureSpec};

/// The objectives of `kinserve ik` (numeric solver only).
#[derive(Debug, Default, Args)]
pub struct IkObjectiveArgs {
    /// Preferred configuration for a redundant arm, comma separated, in the
    /// answer's angle unit: the solution moves towards it while the pose
    /// stays within the tolerance.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub posture: Option<Vec<f64>>,
    /// One weight per joint from 0 to 1 for --posture (default 1 each).
    #[arg(long, value_delimiter = ',', requires = "posture")]
    pub posture_weights: Option<Vec<f64>>,
    /// Tolerance of one axis of the target frame, AXIS=VALUE with AXIS one
    /// of x, y, z (length unit), rx, ry, rz (rad); repeatable or comma separated.
    #[arg(long, value_delimiter = ',', value_parser = parse_axis_tolerance)]
    pub axis_tolerance: Vec<(PoseAxis, f64)>,
    /// An axis of the target frame left free (x, y, z, rx, ry, rz), e.g.
    /// `--free-axis rz` for a tool that may spin; repeatable or comma separated.
    #[arg(long, value_delimiter = ',', value_parser = parse_axis)]
    pub free_axis: Vec<PoseAxis>,
}

impl IkObjectiveArgs {
    /// The request's `posture`.
    pub fn posture(&self) -> Option<PostureSpec> {
        self.posture.clone().map(|joints| PostureSpec {
            joints,
            weights: self.posture_weights.clone(),
        })
    }

    /// The request's `axis_tolerances` (`None` without `--axis-tolerance`).
    pub fn axis_tolerances(&self) -> Option<AxisTolerancesSpec> {
        if self.axis_tolerance.is_empty() {
            return None;
        }
        let mut t = AxisTolerancesSpec::default();
        for (axis, x) in &self.axis_tolerance {
            let slot = match axis {
                PoseAxis::X => &mut t.x,
                PoseAxis::Y => &mut t.y,
                PoseAxis::Z => &mut t.z,
                PoseAxis::Rx => &mut t.rx,
                PoseAxis::Ry => &mut t.ry,
                PoseAxis::Rz => &mut t.rz,
            };
            *slot = Some(*x);
        }
        Some(t)
    }
}

fn parse_axis(s: &str) -> Result<PoseAxis, String> {
    PoseAxis::ALL
        .into_iter()
        .find(|a| a.as_str() == s.trim())
        .ok_or_else(|| format!("unknown axis {s:?}: use x, y, z, rx, ry or rz"))
}

fn parse_axis_tolerance(s: &str) -> Result<(PoseAxis, f64), String> {
    let (axis, value) = s
        .split_once('=')
        .ok_or_else(|| format!("give AXIS=VALUE (e.g. rz=0.01), got {s:?}"))?;
    let x = value
        .trim()
        .parse::<f64>()
        .map_err(|e| format!("{value:?} is not a number: {e}"))?;
    Ok((parse_axis(axis)?, x))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axis_tolerances_parse_by_name_and_refuse_unknown_axes() {
        assert_eq!(parse_axis_tolerance("rz=0.5"), Ok((PoseAxis::Rz, 0.5)));
        assert_eq!(parse_axis(" x"), Ok(PoseAxis::X));
        assert!(parse_axis("w").unwrap_err().contains("rx, ry or rz"));
        assert!(
            parse_axis_tolerance("x")
                .unwrap_err()
                .contains("AXIS=VALUE")
        );
        assert!(parse_axis_tolerance("x=fast").is_err());
        let args = IkObjectiveArgs {
            axis_tolerance: vec![(PoseAxis::X, 1e-3), (PoseAxis::Rz, 0.1)],
            ..IkObjectiveArgs::default()
        };
        let t = args.axis_tolerances().unwrap();
        assert_eq!((t.x, t.y, t.rz), (Some(1e-3), None, Some(0.1)));
        assert_eq!(IkObjectiveArgs::default().axis_tolerances(), None);
    }
}
