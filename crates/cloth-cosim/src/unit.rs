//! A co-simulation unit in the style of FMI 3.0 co-simulation: typed
//! variables with a causality, `do_step` that may be discarded, and state
//! get/set/serialise for rollback.

use std::any::Any;

/// What a variable is to the outside (FMI's causality).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Causality {
    /// Set before the run, constant during it.
    Parameter,
    /// Set by the master before each step.
    Input,
    /// Read by the master after each step.
    Output,
}

/// The value type of a variable (FMI's numeric types). Every value
/// travels as an `f64`: integers up to 2^53 and booleans (0 or 1) exactly;
/// [`settable`] refuses a value the type cannot hold.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum VarType {
    /// A 64-bit float.
    Float64,
    /// A 32-bit float.
    Float32,
    /// An integer of `bits` bits, signed or not (FMI 3.0's `Int8` ..
    /// `UInt64`, FMI 2.0's `Integer` and `Enumeration` as 32-bit signed).
    Integer {
        /// 8, 16, 32 or 64.
        bits: u8,
        /// Signed (`Int*`) or unsigned (`UInt*`).
        signed: bool,
    },
    /// A boolean: 0 is false, 1 is true.
    Boolean,
}

impl VarType {
    /// Why `value` is not a value of this type, if it is not.
    pub fn refuses(self, value: f64) -> Option<String> {
        match self {
            Self::Float64 => None,
            Self::Float32 => (value.abs() > f64::from(f32::MAX)).then(|| "beyond a 32-bit float's range".into()),
            Self::Integer { bits, signed } => {
                let (low, high) = if signed {
                    (-(2f64.powi(i32::from(bits) - 1)), 2f64.powi(i32::from(bits) - 1) - 1.0)
                } else {
                    (0.0, 2f64.powi(i32::from(bits)) - 1.0)
                };
                let name = format!("{}Int{bits}", if signed { "" } else { "U" });
                if value.fract() != 0.0 {
                    Some(format!("not a whole number, as an {name} must be"))
                } else if value < low || value > high {
                    Some(format!("outside an {name}'s range [{low}, {high}]"))
                } else {
                    None
                }
            }
            Self::Boolean => (value != 0.0 && value != 1.0).then(|| "a boolean is 0 or 1".into()),
        }
    }
}

/// One variable of a unit.
#[derive(Debug, Clone, PartialEq)]
pub struct Variable {
    /// Unique name within the unit, e.g. `"pin0.target.x"`.
    pub name: String,
    /// Parameter, input or output.
    pub causality: Causality,
    /// Value type.
    pub ty: VarType,
    /// SI unit, e.g. `"N"`, `"m/s"` (`""` for dimensionless).
    pub unit: &'static str,
    /// What it is.
    pub description: String,
    /// Value before the first step.
    pub start: f64,
    /// Of an output, the inputs of the same unit its value at a
    /// communication point depends on directly (FMI's `dependencies`):
    /// `Some(vec![])` when it depends on none (it changes only in a step),
    /// `None` when unknown, taken as every input.
    pub dependencies: Option<Vec<ValueRef>>,
    /// Of a parameter, whether it may change between steps (FMI's
    /// `variability="tunable"`); otherwise it is fixed once stepping starts.
    pub tunable: bool,
    /// Of an input, the input it is the time derivative of (FMI's
    /// `derivative` attribute): setting it is
    /// [`Unit::set_input_derivative`] of that input.
    pub derivative_of: Option<ValueRef>,
}

impl Variable {
    /// A `Float64` variable.
    pub fn new(
        name: impl Into<String>,
        causality: Causality,
        unit: &'static str,
        description: impl Into<String>,
    ) -> Self {
        Self {
            name: name.into(),
            causality,
            ty: VarType::Float64,
            unit,
            description: description.into(),
            start: 0.0,
            dependencies: None,
            tunable: false,
            derivative_of: None,
        }
    }

    /// The same output, depending directly on the inputs `inputs` only
    /// (none: it changes only in a step).
    pub fn with_dependencies(mut self, inputs: Vec<ValueRef>) -> Self {
        self.dependencies = Some(inputs);
        self
    }

    /// The same parameter, tunable between steps.
    pub fn tunable(mut self) -> Self {
        self.tunable = true;
        self
    }

    /// The same input, the time derivative of input `of`.
    pub fn derivative_of(mut self, of: ValueRef) -> Self {
        self.derivative_of = Some(of);
        self
    }

    /// The same variable with value type `ty`.
    pub fn with_type(mut self, ty: VarType) -> Self {
        self.ty = ty;
        self
    }

    /// The same variable with start value `start`.
    pub fn with_start(mut self, start: f64) -> Self {
        self.start = start;
        self
    }
}

/// Index of a variable in [`Unit::variables`] (FMI's value reference).
pub type ValueRef = usize;

/// How a step ended.
#[derive(Debug, Clone, PartialEq)]
pub enum StepOutcome {
    /// The unit reached `t + h`.
    Completed,
    /// The unit could not complete the step (FMI's `fmi3Discard`) and
    /// stopped at `last_time_s`; its state is valid there.
    Discarded {
        /// The time the unit reached, s.
        last_time_s: f64,
        /// Why.
        reason: String,
    },
}

/// A unit's saved state: opaque, only its own unit reads it.
pub struct UnitState(pub Box<dyn Any + Send>);

impl UnitState {
    /// The state as the `T` unit `unit` saved, or a `BadState` error saying
    /// it is not a state of a `kind`.
    pub fn downcast<T: 'static>(&self, unit: &str, kind: &str) -> Result<&T, UnitError> {
        self.0
            .downcast_ref::<T>()
            .ok_or_else(|| UnitError::BadState { unit: unit.to_string(), message: format!("not a state of a {kind}") })
    }
}

impl std::fmt::Debug for UnitState {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("UnitState(..)")
    }
}

/// Why a unit refused a call.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum UnitError {
    /// No variable with this value reference.
    #[error("{unit}: no variable {vr} (it has {count})")]
    NoSuchVariable {
        /// The unit.
        unit: String,
        /// The value reference given.
        vr: ValueRef,
        /// Variables of the unit.
        count: usize,
    },
    /// The variable's causality forbids this call (e.g. setting an output).
    #[error("{unit}: {name} is an {causality:?}: {message}")]
    Causality {
        /// The unit.
        unit: String,
        /// The variable.
        name: String,
        /// Its causality.
        causality: Causality,
        /// What was refused.
        message: &'static str,
    },
    /// A value that is not finite or out of range.
    #[error("{unit}: {name} = {value}: {message}")]
    InvalidValue {
        /// The unit.
        unit: String,
        /// The variable.
        name: String,
        /// The value.
        value: f64,
        /// Why.
        message: String,
    },
    /// The unit does not support this call.
    #[error("{unit}: {what} is not supported")]
    Unsupported {
        /// The unit.
        unit: String,
        /// The call.
        what: &'static str,
    },
    /// A step failed for good (not a discard: the state is not usable).
    #[error("{unit}: step from t = {time_s} s failed: {message}")]
    StepFailed {
        /// The unit.
        unit: String,
        /// Start of the step, s.
        time_s: f64,
        /// What went wrong.
        message: String,
    },
    /// A saved state does not belong to this unit or is corrupt.
    #[error("{unit}: bad state: {message}")]
    BadState {
        /// The unit.
        unit: String,
        /// Why.
        message: String,
    },
}

/// A co-simulation unit. An input is its value at the communication point
/// where it is set (FMI's meaning). Over the step that follows, the unit
/// sees it move at the derivative the master gave
/// ([`Unit::set_input_derivative`]), or, without one, as the unit
/// documents: held (most units), or continued from the previous
/// communication point's value (the cloth's pins). A unit that refuses
/// derivatives holds its inputs, so a derivative of 0 is what it does.
pub trait Unit: Send {
    /// The unit's name, for messages.
    fn name(&self) -> &str;

    /// Every variable; a [`ValueRef`] indexes this slice.
    fn variables(&self) -> &[Variable];

    /// Sets an input (or a parameter before the first step).
    fn set(&mut self, vr: ValueRef, value: f64) -> Result<(), UnitError>;

    /// Sets the time derivative of an input over the next step, per
    /// second: the unit then sees `u(t) = u(t0) + du (t - t0)` (FMI 2's
    /// input derivatives). Units that hold inputs constant refuse it.
    /// Whether a derivative outlives the step or a later [`Unit::set`] of
    /// the value is the unit's to document.
    fn set_input_derivative(&mut self, vr: ValueRef, _du: f64) -> Result<(), UnitError> {
        let _ = vr;
        Err(UnitError::Unsupported { unit: self.name().to_string(), what: "input derivatives" })
    }

    /// Reads a variable.
    fn get(&self, vr: ValueRef) -> Result<f64, UnitError>;

    /// Advances from `t` to `t + h` (s) with the inputs set.
    fn do_step(&mut self, t: f64, h: f64) -> Result<StepOutcome, UnitError>;

    /// The complete state (FMI's `fmi3GetFMUState`).
    fn get_state(&self) -> UnitState;

    /// Returns to a state from [`Unit::get_state`] of this unit.
    fn set_state(&mut self, state: &UnitState) -> Result<(), UnitError>;

    /// A state as bytes (FMI's `fmi3SerializeFMUState`).
    fn serialize_state(&self, state: &UnitState) -> Result<Vec<u8>, UnitError>;

    /// A state from bytes written by [`Unit::serialize_state`].
    fn deserialize_state(&self, bytes: &[u8]) -> Result<UnitState, UnitError>;

    /// The value reference of the variable called `name`.
    fn find(&self, name: &str) -> Option<ValueRef> {
        self.variables().iter().position(|v| v.name == name)
    }
}

/// Checks that `vr` exists and may be set; returns its variable.
pub fn settable<'a>(unit: &str, vars: &'a [Variable], vr: ValueRef, value: f64) -> Result<&'a Variable, UnitError> {
    let var = vars.get(vr).ok_or(UnitError::NoSuchVariable { unit: unit.into(), vr, count: vars.len() })?;
    if var.causality == Causality::Output {
        return Err(UnitError::Causality {
            unit: unit.into(),
            name: var.name.clone(),
            causality: var.causality,
            message: "outputs cannot be set",
        });
    }
    if !(value.is_finite() && value.abs() <= MAX_INPUT) {
        return Err(UnitError::InvalidValue {
            unit: unit.into(),
            name: var.name.clone(),
            value,
            message: format!("must be finite and within +-{MAX_INPUT:e} (its square must not overflow)"),
        });
    }
    if let Some(why) = var.ty.refuses(value) {
        return Err(UnitError::InvalidValue { unit: unit.into(), name: var.name.clone(), value, message: why });
    }
    Ok(var)
}

/// The largest magnitude an input may have: squares and products of two
/// inputs (distances, energies) stay finite below it.
pub const MAX_INPUT: f64 = 1e150;

/// Little-endian `f64` packing for state serialisation: a tag naming the
/// kind of unit, the format's version, the values, and a CRC-32 of all
/// that, so that a state of another kind of unit, of another version, cut
/// short or changed in any byte is refused, never read.
pub mod bytes {
    /// The layout this build writes and reads.
    /// 2: the cloth unit's state records `newton_engaged`.
    /// 3: the cloth unit's state records its inputs at the previous
    /// communication point and which rates were given.
    /// 4: the cloth unit's state records its integrator's memory (as
    /// many values as it has) in place of `next_dt` and `newton_engaged`.
    pub const FORMAT_VERSION: u32 = 4;

    /// Writes `tag`, [`FORMAT_VERSION`], the values and the checksum.
    pub fn pack(tag: &[u8; 8], values: impl IntoIterator<Item = f64>) -> Vec<u8> {
        let mut out = tag.to_vec();
        out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
        for v in values {
            out.extend_from_slice(&v.to_le_bytes());
        }
        let crc = crc32fast::hash(&out);
        out.extend_from_slice(&crc.to_le_bytes());
        out
    }

    /// Reads the values of bytes [`pack`] wrote with `tag`; why not when
    /// the tag, the version, the length or the checksum is wrong.
    pub fn unpack(tag: &[u8; 8], bytes: &[u8]) -> Result<Vec<f64>, String> {
        let Some(rest) = bytes.strip_prefix(&tag[..]) else {
            return Err("its tag is not this kind of unit's".into());
        };
        if rest.len() < 8 {
            return Err("cut short".into());
        }
        let (body, crc) = bytes.split_at(bytes.len() - 4);
        let version = u32::from_le_bytes(rest[..4].try_into().expect("4 bytes"));
        if version != FORMAT_VERSION {
            return Err(format!("format version {version}; this build reads version {FORMAT_VERSION}"));
        }
        if crc32fast::hash(body).to_le_bytes() != crc {
            return Err("its checksum does not match: changed or cut short".into());
        }
        let values = &body[tag.len() + 4..];
        if values.len() % 8 != 0 {
            return Err("not a whole number of values".into());
        }
        Ok(values.chunks_exact(8).map(|c| f64::from_le_bytes(c.try_into().expect("chunks of 8"))).collect())
    }
}

#[cfg(test)]
mod tests {
    use super::bytes::{FORMAT_VERSION, pack, unpack};
    use super::{Causality, UnitError, VarType, Variable, settable};

    #[test]
    fn a_value_the_type_cannot_hold_is_refused_by_name() {
        let int8 = VarType::Integer { bits: 8, signed: true };
        let uint64 = VarType::Integer { bits: 64, signed: false };
        for (ty, good, bad) in [
            (int8, [-128.0, 127.0], [128.0, 1.5]),
            (VarType::Integer { bits: 16, signed: false }, [0.0, 65535.0], [-1.0, 65536.0]),
            (uint64, [0.0, 2f64.powi(53)], [-1.0, 0.5]),
            (VarType::Boolean, [0.0, 1.0], [0.5, 2.0]),
            (VarType::Float32, [3.4e38, -1e-40], [3.5e38, -1e39]),
        ] {
            let vars = [Variable::new("n", Causality::Input, "", "").with_type(ty)];
            for v in good {
                assert!(settable("u", &vars, 0, v).is_ok(), "{ty:?} {v}");
            }
            for v in bad {
                match settable("u", &vars, 0, v) {
                    Err(UnitError::InvalidValue { name, .. }) => assert_eq!(name, "n"),
                    other => panic!("{ty:?} {v}: {other:?}"),
                }
            }
        }
    }

    const TAG: &[u8; 8] = b"testunit";

    #[test]
    fn packed_values_come_back_and_any_changed_byte_is_refused() {
        let values = [1.5, -2.0e-300, f64::MAX, 0.0];
        let bytes = pack(TAG, values);
        assert_eq!(unpack(TAG, &bytes).unwrap(), values);
        for k in 0..bytes.len() {
            for bit in 0..8 {
                let mut flipped = bytes.clone();
                flipped[k] ^= 1 << bit;
                assert!(unpack(TAG, &flipped).is_err(), "byte {k} bit {bit} flipped was read");
            }
        }
        for cut in 0..bytes.len() {
            assert!(unpack(TAG, &bytes[..cut]).is_err(), "cut to {cut} bytes was read");
        }
        assert!(unpack(b"otherone", &bytes).unwrap_err().contains("tag"));
    }

    #[test]
    fn another_format_version_is_refused_by_name() {
        let mut bytes = TAG.to_vec();
        bytes.extend_from_slice(&(FORMAT_VERSION + 1).to_le_bytes());
        bytes.extend_from_slice(&1.0f64.to_le_bytes());
        let crc = crc32fast::hash(&bytes);
        bytes.extend_from_slice(&crc.to_le_bytes());
        let why = unpack(TAG, &bytes).unwrap_err();
        assert!(why.contains(&format!("format version {}", FORMAT_VERSION + 1)), "{why}");
    }
}
