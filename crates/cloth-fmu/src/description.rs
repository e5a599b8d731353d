//! `modelDescription.xml` (FMI 3.0) generated from a unit's variables.

use crate::MODEL_IDENTIFIER;
use cloth_cosim::{Causality, Variable};
use std::fmt::Write;

/// What the model description says besides the variables.
#[derive(Debug, Clone)]
pub struct FmuInfo {
    /// `modelName` (the scene file's stem).
    pub model_name: String,
    /// `instantiationToken`, checked by `fmi3InstantiateCoSimulation`.
    pub token: String,
    /// One line on what the FMU is.
    pub description: String,
    /// The scene's time step: `DefaultExperiment stepSize`, s.
    pub step_s: f64,
    /// The scene's duration: `DefaultExperiment stopTime`, s.
    pub stop_s: f64,
}

/// An array output of the FMU (FMI 3.0 `<Dimension>`): one row of
/// `x, y, z` per particle, row-major, as `fmi3GetFloat64` hands it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArrayOutput {
    /// Variable name.
    pub name: &'static str,
    /// SI unit.
    pub unit: &'static str,
    /// What it is.
    pub description: &'static str,
    /// Rows (particles).
    pub rows: usize,
}

impl ArrayOutput {
    /// Values it holds: `3 rows`.
    pub fn len(&self) -> usize {
        3 * self.rows
    }

    /// Whether it holds none (a cloth without particles; never built).
    pub fn is_empty(&self) -> bool {
        self.rows == 0
    }
}

/// The FMU's array outputs for a cloth of `particles` particles, after the
/// unit's variables: every particle's position (m) and velocity (m/s) at
/// the communication point.
pub fn array_outputs(particles: usize) -> [ArrayOutput; 2] {
    [
        ArrayOutput {
            name: "positions",
            unit: "m",
            description: "every particle's position, x y z per row",
            rows: particles,
        },
        ArrayOutput {
            name: "velocities",
            unit: "m/s",
            description: "every particle's velocity, x y z per row",
            rows: particles,
        },
    ]
}

/// The SI units the cloth's variables use, with their base-unit exponents
/// (`kg`, `m`, `s`, `rad`). The model description declares them; an
/// imported FMU's unit names are mapped back to these.
pub(crate) const UNITS: [(&str, [i32; 4]); 8] = [
    ("s", [0, 0, 1, 0]),
    ("m", [0, 1, 0, 0]),
    ("m/s", [0, 1, -1, 0]),
    ("m/s2", [0, 1, -2, 0]),
    ("N", [1, 1, -2, 0]),
    ("N.m", [1, 2, -2, 0]),
    ("rad", [0, 0, 0, 1]),
    ("rad/s", [0, 0, -1, 1]),
];

/// The table's entry of `unit`, if it has one.
pub(crate) fn known_unit(unit: &str) -> Option<(&'static str, [i32; 4])> {
    UNITS.iter().find(|(name, _)| *name == unit).copied()
}

/// Escapes `&`, `<`, `>` and `"` for an XML attribute.
fn escape(text: &str) -> String {
    text.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// Formats a start value so that it reads back as the same `f64`.
fn number(x: f64) -> String {
    format!("{x:?}")
}

/// The model description of an FMU whose unit has `variables` (value
/// reference `k + 1` for variable `k`; 0 is `time`). Every output is an
/// `InitialUnknown` (computed from the initial state), and depends on no
/// input at its communication point (`dependencies=""`): outputs change
/// only in `fmi3DoStep`, from the step's result, so an input set at a
/// communication point reaches them through the next step's state, never
/// directly, and a master sees no algebraic loop through the cloth. Dimensionless
/// variables (unit `"1"` or `""`) carry no unit. The `arrays` follow the
/// variables (value references from `variables.len() + 1`), outputs too.
pub fn model_description(variables: &[Variable], arrays: &[ArrayOutput], info: &FmuInfo) -> String {
    // `s` first (time's unit), then the variables' in order of appearance.
    let mut units: Vec<(&str, [i32; 4])> = vec![UNITS[0]];
    for unit in variables.iter().map(|v| v.unit).chain(arrays.iter().map(|a| a.unit)).filter_map(known_unit) {
        if !units.contains(&unit) {
            units.push(unit);
        }
    }
    let mut x = String::new();
    let _ = writeln!(x, r#"<?xml version="1.0" encoding="UTF-8"?>"#);
    let _ = writeln!(
        x,
        r#"<fmiModelDescription fmiVersion="3.0" modelName="{}" description="{}" instantiationToken="{}" generationTool="cloth-fmu {}" variableNamingConvention="structured">"#,
        escape(&info.model_name),
        escape(&info.description),
        escape(&info.token),
        env!("CARGO_PKG_VERSION"),
    );
    let _ = writeln!(
        x,
        r#"  <CoSimulation modelIdentifier="{MODEL_IDENTIFIER}" canHandleVariableCommunicationStepSize="true" canGetAndSetFMUState="true" canSerializeFMUState="true" hasEventMode="false"/>"#
    );
    let _ = writeln!(x, "  <UnitDefinitions>");
    for &(unit, [kg, m, s, rad]) in &units {
        let mut attrs = String::new();
        for (name, e) in [("kg", kg), ("m", m), ("s", s), ("rad", rad)] {
            if e != 0 {
                let _ = write!(attrs, r#" {name}="{e}""#);
            }
        }
        let _ = writeln!(x, r#"    <Unit name="{}"><BaseUnit{attrs}/></Unit>"#, escape(unit));
    }
    let _ = writeln!(x, "  </UnitDefinitions>");
    let _ = writeln!(x, r#"  <LogCategories>"#);
    for (name, what) in [
        ("logEvents", "initialisation, steps, states"),
        ("logStatusError", "calls that failed: why"),
        ("logStatusDiscard", "steps the cloth could not take: why"),
    ] {
        let _ = writeln!(x, r#"    <Category name="{name}" description="{what}"/>"#);
    }
    let _ = writeln!(x, r#"  </LogCategories>"#);
    let _ = writeln!(
        x,
        r#"  <DefaultExperiment startTime="0.0" stopTime="{}" stepSize="{}"/>"#,
        number(info.stop_s),
        number(info.step_s)
    );
    let _ = writeln!(x, "  <ModelVariables>");
    let _ = writeln!(
        x,
        r#"    <Float64 name="time" valueReference="0" causality="independent" variability="continuous" unit="s" description="simulation time"/>"#
    );
    for (k, v) in variables.iter().enumerate() {
        let causality = match v.causality {
            Causality::Parameter => "parameter",
            Causality::Input => "input",
            Causality::Output => "output",
        };
        let variability = match v.causality {
            Causality::Parameter if v.tunable => "tunable",
            Causality::Parameter => "fixed",
            _ => "continuous",
        };
        let unit = if known_unit(v.unit).is_some() { format!(r#" unit="{}""#, escape(v.unit)) } else { String::new() };
        let start =
            if v.causality == Causality::Output { String::new() } else { format!(r#" start="{}""#, number(v.start)) };
        let derivative = v.derivative_of.map_or(String::new(), |of| format!(r#" derivative="{}""#, of + 1));
        let _ = writeln!(
            x,
            r#"    <Float64 name="{}" valueReference="{}" causality="{causality}" variability="{variability}"{unit}{start}{derivative} description="{}"/>"#,
            escape(&v.name),
            k + 1,
            escape(&v.description)
        );
    }
    for (k, a) in arrays.iter().enumerate() {
        let _ = writeln!(
            x,
            r#"    <Float64 name="{}" valueReference="{}" causality="output" variability="continuous" unit="{}" description="{}"><Dimension start="{}"/><Dimension start="3"/></Float64>"#,
            escape(a.name),
            variables.len() + k + 1,
            escape(a.unit),
            escape(a.description),
            a.rows
        );
    }
    let _ = writeln!(x, "  </ModelVariables>");
    let _ = writeln!(x, "  <ModelStructure>");
    let outputs: Vec<usize> = variables
        .iter()
        .enumerate()
        .filter(|(_, v)| v.causality == Causality::Output)
        .map(|(k, _)| k + 1)
        .chain((0..arrays.len()).map(|k| variables.len() + k + 1))
        .collect();
    for vr in &outputs {
        let _ = writeln!(x, r#"    <Output valueReference="{vr}" dependencies=""/>"#);
    }
    for vr in &outputs {
        let _ = writeln!(x, r#"    <InitialUnknown valueReference="{vr}" dependencies=""/>"#);
    }
    let _ = writeln!(x, "  </ModelStructure>");
    let _ = writeln!(x, "</fmiModelDescription>");
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn variables_units_and_structure() {
        let vars = vec![
            Variable::new("pin0.target.x", Causality::Input, "m", "pin <x> & \"y\"").with_start(0.25),
            Variable::new("solid0.torque.z", Causality::Output, "N.m", "torque"),
            Variable::new("max_stretch", Causality::Output, "1", "ratio"),
            Variable::new("pin0.target_rate.x", Causality::Input, "m/s", "rate").derivative_of(0),
        ];
        let info = FmuInfo {
            model_name: "hang".into(),
            token: "{abc}".into(),
            description: "a cloth".into(),
            step_s: 1.0 / 90.0,
            stop_s: 2.0,
        };
        let xml = model_description(&vars, &array_outputs(7), &info);
        assert!(xml.contains(
            r#"<Float64 name="pin0.target.x" valueReference="1" causality="input" variability="continuous" unit="m" start="0.25" description="pin &lt;x&gt; &amp; &quot;y&quot;"/>"#
        ));
        assert!(xml.contains(r#"<Float64 name="max_stretch" valueReference="3" causality="output" variability="continuous" description="ratio"/>"#));
        assert!(xml.contains(r#"<Unit name="N.m"><BaseUnit kg="1" m="2" s="-2"/></Unit>"#));
        assert!(xml.contains(r#"valueReference="4" causality="input" variability="continuous" unit="m/s" start="0.0" derivative="1" description="rate"/>"#));
        assert!(xml.contains(r#"stepSize="0.011111111111111112""#));
        // Outputs are listed, and listed as initial unknowns, with no direct
        // feedthrough; inputs are not.
        for vr in [2, 3] {
            assert!(xml.contains(&format!(r#"<Output valueReference="{vr}" dependencies=""/>"#)));
            assert!(xml.contains(&format!(r#"<InitialUnknown valueReference="{vr}" dependencies=""/>"#)));
        }
        assert!(!xml.contains(r#"<Output valueReference="1""#));
        assert!(xml.contains(r#"<Float64 name="velocities" valueReference="6" causality="output" variability="continuous" unit="m/s" description="every particle's velocity, x y z per row"><Dimension start="7"/><Dimension start="3"/></Float64>"#));
        assert!(xml.contains(r#"<Output valueReference="6" dependencies=""/>"#));
    }
}
