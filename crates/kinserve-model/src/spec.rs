//! The robot model schema as clients write it (robot files, REST bodies, and
//! field by field the gRPC messages). Plain data: see [`crate::Robot`] for the
//! validated form the math accepts.

use serde::{Deserialize, Serialize};

/// Implements `Serialize` and `Deserialize` for a struct derived with
/// `#[serde(remote = "Self")]` so that it is read only from a JSON object:
/// serde's derive alone also accepts an array of the field values in
/// declaration order (`"tool": [null, null]`), which the schema does not allow.
macro_rules! object_only {
    ($t:ident) => {
        impl Serialize for $t {
            fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
                // The inherent function derived by `remote = "Self"`.
                $t::serialize(self, s)
            }
        }

        impl<'de> Deserialize<'de> for $t {
            fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
                struct ObjectVisitor;
                impl<'de> serde::de::Visitor<'de> for ObjectVisitor {
                    type Value = $t;
                    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                        f.write_str("a JSON object")
                    }
                    fn visit_map<A: serde::de::MapAccess<'de>>(
                        self,
                        map: A,
                    ) -> Result<$t, A::Error> {
                        $t::deserialize(serde::de::value::MapAccessDeserializer::new(map))
                    }
                }
                d.deserialize_map(ObjectVisitor)
            }
        }
    };
}
pub(crate) use object_only;

/// DH convention of a table.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "lowercase")]
pub enum ConventionSpec {
    /// Standard (distal): `A_i = Rz(θ_i)·Tz(d_i)·Tx(a_i)·Rx(α_i)`.
    Standard,
    /// Modified (proximal, Craig): `A_i = Rx(α_{i-1})·Tx(a_{i-1})·Rz(θ_i)·Tz(d_i)`; row `i` holds `α_{i-1}, a_{i-1}, θ_i, d_i`.
    Modified,
}

/// Kind of joint of a DH row.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "lowercase")]
pub enum JointType {
    /// The joint value is added to `theta`.
    Revolute,
    /// The joint value is added to `d`.
    Prismatic,
    /// No joint variable (a constant frame written as a row).
    Fixed,
}

/// Unit of angles: `alpha`, `theta`, revolute limits, base/tool `rpy` in a model;
/// joint values in an FK request.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "lowercase")]
pub enum AngleUnit {
    /// Radians (the default).
    #[default]
    Rad,
    /// Degrees.
    Deg,
}

impl AngleUnit {
    /// Factor that turns a value in this unit into radians.
    pub fn to_rad(self) -> f64 {
        match self {
            AngleUnit::Rad => 1.0,
            AngleUnit::Deg => std::f64::consts::PI / 180.0,
        }
    }

    /// Short name as written in JSON (`rad`, `deg`).
    pub fn as_str(self) -> &'static str {
        match self {
            AngleUnit::Rad => "rad",
            AngleUnit::Deg => "deg",
        }
    }
}

/// Unit of lengths: `a`, `d`, prismatic limits and joint values, base/tool
/// translations, and every position FK returns for the robot.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(rename_all = "lowercase")]
pub enum LengthUnit {
    /// Metres (the default).
    #[default]
    M,
    /// Millimetres.
    Mm,
}

impl LengthUnit {
    /// Short name as written in JSON (`m`, `mm`).
    pub fn as_str(self) -> &'static str {
        match self {
            LengthUnit::M => "m",
            LengthUnit::Mm => "mm",
        }
    }
}

/// One row of the DH table.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields, remote = "Self")]
pub struct LinkSpec {
    /// Optional joint/link name: 1–64 characters, no control, bidirectional-text
    /// control, separator or noncharacter code points (see [`crate::check_label`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "openapi", schema(max_length = 64))]
    pub name: Option<String>,
    /// Joint kind.
    pub joint: JointType,
    /// Link length `a` (modified: `a_{i-1}`), model length unit; at most 1e9 in magnitude.
    #[cfg_attr(feature = "openapi", schema(minimum = -1e9, maximum = 1e9))]
    pub a: f64,
    /// Link twist `α` (modified: `α_{i-1}`), model angle unit; at most 1e9 in magnitude.
    #[cfg_attr(feature = "openapi", schema(minimum = -1e9, maximum = 1e9))]
    pub alpha: f64,
    /// Link offset `d`; for a prismatic joint the value at q = 0. Model length unit; at most 1e9 in magnitude.
    #[cfg_attr(feature = "openapi", schema(minimum = -1e9, maximum = 1e9))]
    pub d: f64,
    /// Joint angle `θ`; for a revolute joint the value at q = 0. Model angle unit; at most 1e9 in magnitude.
    #[cfg_attr(feature = "openapi", schema(minimum = -1e9, maximum = 1e9))]
    pub theta: f64,
    /// Joint limits `[lo, hi]` on q (not on θ or d): angle unit for revolute,
    /// length unit for prismatic joints (within ±1e9). Not allowed on fixed rows.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub limits: Option<[f64; 2]>,
}

/// A unit quaternion `w + xi + yj + zk` (normalised on input; must not be zero).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields, remote = "Self")]
pub struct QuaternionSpec {
    /// Scalar part.
    pub w: f64,
    /// i component.
    pub x: f64,
    /// j component.
    pub y: f64,
    /// k component.
    pub z: f64,
}

/// A fixed rigid transform: either `translation` with at most one of `rpy` /
/// `quaternion`, or `matrix` alone.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields, remote = "Self")]
pub struct TransformSpec {
    /// `[x, y, z]` in the model length unit (default zero), each at most 1e9 in magnitude.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub translation: Option<[f64; 3]>,
    /// `[roll, pitch, yaw]` in the model angle unit, `R = Rz(yaw)·Ry(pitch)·Rx(roll)`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rpy: Option<[f64; 3]>,
    /// Orientation as a quaternion.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub quaternion: Option<QuaternionSpec>,
    /// Homogeneous 4×4 matrix, row-major; must be rigid (orthonormal rotation,
    /// det +1 within 1e-6, last row 0 0 0 1); the nearest exact rotation is used.
    /// Translation in the model length unit, each at most 1e9 in magnitude.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub matrix: Option<[[f64; 4]; 4]>,
}

/// A serial robot as registered: a named DH table with units and optional base and tool.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields, remote = "Self")]
#[cfg_attr(feature = "openapi", schema(example = json!({
    "name": "planar2",
    "convention": "standard",
    "angle_unit": "deg",
    "length_unit": "m",
    "links": [
        {"joint": "revolute", "a": 0.5, "alpha": 0, "d": 0, "theta": 0, "limits": [-170, 170]},
        {"joint": "revolute", "a": 0.3, "alpha": 0, "d": 0, "theta": 0}
    ]
})))]
pub struct RobotSpec {
    /// 1–64 characters of `[a-z0-9_-]`, starting with a letter or digit.
    #[cfg_attr(
        feature = "openapi",
        schema(
            pattern = "^[a-z0-9][a-z0-9_-]{0,63}$",
            min_length = 1,
            max_length = 64
        )
    )]
    pub name: String,
    /// Free text (at most 4096 characters; tab and line breaks allowed, other
    /// control characters not: see [`crate::check_text`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "openapi", schema(max_length = 4096))]
    pub description: Option<String>,
    /// Where the table comes from (at most 4096 characters, as `description`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[cfg_attr(feature = "openapi", schema(max_length = 4096))]
    pub source: Option<String>,
    /// DH convention of `links`.
    pub convention: ConventionSpec,
    /// Unit of angles in this model (default `rad`).
    #[serde(default)]
    pub angle_unit: AngleUnit,
    /// Unit of lengths in this model and in its FK results (default `m`).
    #[serde(default)]
    pub length_unit: LengthUnit,
    /// Robot base in the world frame (`^world T_0`); identity if absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub base: Option<TransformSpec>,
    /// Tool tip in the flange frame (`^n T_tool`); identity if absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tool: Option<TransformSpec>,
    /// The DH table, base to flange (at least one row, at least one of them movable).
    #[cfg_attr(feature = "openapi", schema(min_items = 1))]
    pub links: Vec<LinkSpec>,
}

object_only!(LinkSpec);
object_only!(QuaternionSpec);
object_only!(TransformSpec);
object_only!(RobotSpec);
