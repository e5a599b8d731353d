//! What the importer reads of a `modelDescription.xml`, FMI 3.0 or 2.0,
//! parsed with `quick-xml`.

use crate::description::known_unit;
use cloth_cosim::{Causality, VarType};

/// The FMI version of a model description.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Version {
    /// FMI 3.0: `fmi3*` functions, `binaries/x86_64-linux/`.
    Fmi3,
    /// FMI 2.0: `fmi2*` functions, `binaries/linux64/`.
    Fmi2,
}

/// A variable's type as the FMU declares it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Kind {
    /// A number (or boolean): a unit variable.
    Number(VarType),
    /// A string: set and read by name on the unit, never connected.
    String,
}

/// One scalar variable of causality input, output or parameter.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Declared {
    pub name: String,
    pub causality: Causality,
    pub kind: Kind,
    pub vr: u32,
    /// The start value as written (`None`: none given).
    pub start: Option<String>,
    /// One of this crate's SI unit names, when the FMU's unit is one.
    pub unit: &'static str,
    pub description: String,
    /// The value reference of the variable this one is the derivative of.
    pub derivative_of: Option<u32>,
    /// `variability="tunable"`.
    pub tunable: bool,
}

/// The model description's parts the importer uses.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Description {
    pub version: Version,
    /// `instantiationToken` (3.0) or `guid` (2.0).
    pub token: String,
    /// `<CoSimulation modelIdentifier>`.
    pub identifier: String,
    /// `canGetAndSetFMUState` and `canSerializeFMUState` (both needed for rollback).
    pub can_save_state: bool,
    /// FMI 2.0's `canInterpolateInputs` (`fmi2SetRealInputDerivatives`).
    pub can_interpolate: bool,
    pub variables: Vec<Declared>,
    /// Each `<Output>`'s value reference and its `dependencies`, if given.
    pub outputs: Vec<(u32, Option<Vec<u32>>)>,
    /// Variables passed over (arrays, binaries, clocks), with why.
    pub passed_over: Vec<String>,
}

/// FMI 3.0's type elements and their value types.
fn fmi3_kind(element: &[u8]) -> Option<Kind> {
    let int = |bits, signed| Some(Kind::Number(VarType::Integer { bits, signed }));
    match element {
        b"Float64" => Some(Kind::Number(VarType::Float64)),
        b"Float32" => Some(Kind::Number(VarType::Float32)),
        b"Int8" => int(8, true),
        b"UInt8" => int(8, false),
        b"Int16" => int(16, true),
        b"UInt16" => int(16, false),
        b"Int32" => int(32, true),
        b"UInt32" => int(32, false),
        b"Int64" => int(64, true),
        b"UInt64" => int(64, false),
        b"Boolean" => Some(Kind::Number(VarType::Boolean)),
        b"String" => Some(Kind::String),
        _ => None,
    }
}

/// FMI 2.0's type elements inside a `<ScalarVariable>`.
fn fmi2_kind(element: &[u8]) -> Option<Kind> {
    match element {
        b"Real" => Some(Kind::Number(VarType::Float64)),
        b"Integer" | b"Enumeration" => Some(Kind::Number(VarType::Integer { bits: 32, signed: true })),
        b"Boolean" => Some(Kind::Number(VarType::Boolean)),
        b"String" => Some(Kind::String),
        _ => None,
    }
}

fn causality(text: Option<&str>) -> Option<Causality> {
    // The default is local; independent (time), calculated and structural
    // parameters are not the master's to set or read.
    match text.unwrap_or("local") {
        "input" => Some(Causality::Input),
        "output" => Some(Causality::Output),
        "parameter" => Some(Causality::Parameter),
        _ => None,
    }
}

type Attributes = std::collections::BTreeMap<String, String>;

fn attributes(element: &quick_xml::events::BytesStart) -> Result<Attributes, String> {
    let mut out = Attributes::new();
    for a in element.attributes() {
        let a = a.map_err(|e| format!("XML attribute: {e}"))?;
        let value = a.unescape_value().map_err(|e| format!("XML attribute value: {e}"))?;
        out.insert(String::from_utf8_lossy(a.key.as_ref()).into_owned(), value.into_owned());
    }
    Ok(out)
}

/// A variable being read: its own attributes, then (2.0) its type
/// element's, and (3.0) whether a `<Dimension>` made it an array.
struct Open {
    attributes: Attributes,
    kind: Option<Kind>,
    type_attributes: Attributes,
    array: bool,
    /// A string's `<Start value>` (3.0).
    start: Option<String>,
}

/// Parses a model description: version, token, co-simulation identifier
/// and flags, the scalar input, output and parameter variables of every
/// type, and the outputs' dependencies. Errors name what is missing or
/// malformed.
pub(crate) fn parse_description(xml: &str) -> Result<Description, String> {
    use quick_xml::events::Event;
    let mut reader = quick_xml::Reader::from_str(xml);
    let mut root = false;
    let mut d = Description {
        version: Version::Fmi3,
        token: String::new(),
        identifier: String::new(),
        can_save_state: false,
        can_interpolate: false,
        variables: Vec::new(),
        outputs: Vec::new(),
        passed_over: Vec::new(),
    };
    let (mut token, mut identifier) = (None, None);
    // FMI 2.0 refers to variables by 1-based position: every
    // ScalarVariable's value reference in order, and references to resolve.
    let mut positions: Vec<u32> = Vec::new();
    let mut fmi2_derivatives: Vec<(usize, usize)> = Vec::new();
    let mut fmi2_outputs: Vec<(usize, Option<Vec<usize>>)> = Vec::new();
    let mut in_outputs = false;
    let mut open: Option<Open> = None;
    loop {
        let event = reader.read_event().map_err(|e| format!("XML at byte {}: {e}", reader.buffer_position()))?;
        let (element, empty) = match &event {
            Event::Start(e) => (e, false),
            Event::Empty(e) => (e, true),
            Event::End(e) => {
                match e.name().as_ref() {
                    b"Outputs" => in_outputs = false,
                    name if open.is_some()
                        && match d.version {
                            Version::Fmi2 => name == b"ScalarVariable",
                            Version::Fmi3 => fmi3_kind(name).is_some() || name == b"Binary" || name == b"Clock",
                        } =>
                    {
                        let closing = open.take().expect("checked");
                        finish(&mut d, closing, &mut positions, &mut fmi2_derivatives)?;
                    }
                    _ => {}
                }
                continue;
            }
            Event::Eof => break,
            _ => continue,
        };
        let a = attributes(element)?;
        let name = element.name();
        match name.as_ref() {
            b"fmiModelDescription" => {
                d.version = match a.get("fmiVersion").map(String::as_str) {
                    Some(v) if v.starts_with("3.") => Version::Fmi3,
                    Some(v) if v.starts_with("2.") => Version::Fmi2,
                    other => return Err(format!("fmiVersion {other:?}: only FMI 3.0 and 2.0 are read")),
                };
                root = true;
                token = a.get("instantiationToken").or_else(|| a.get("guid")).cloned();
            }
            b"CoSimulation" => {
                identifier = a.get("modelIdentifier").cloned();
                let yes = |k: &str| a.get(k).is_some_and(|v| v == "true");
                d.can_save_state = (yes("canGetAndSetFMUState") || yes("canGetAndSetFMUstate"))
                    && (yes("canSerializeFMUState") || yes("canSerializeFMUstate"));
                d.can_interpolate = yes("canInterpolateInputs");
            }
            b"Outputs" => in_outputs = true,
            b"Output" => {
                let Some(vr) = a.get("valueReference").and_then(|v| v.parse().ok()) else { continue };
                let dependencies =
                    a.get("dependencies").map(|l| l.split_whitespace().filter_map(|v| v.parse().ok()).collect());
                d.outputs.push((vr, dependencies));
            }
            b"Unknown" if in_outputs => {
                let Some(index) = a.get("index").and_then(|v| v.parse().ok()) else { continue };
                let dependencies =
                    a.get("dependencies").map(|l| l.split_whitespace().filter_map(|v| v.parse().ok()).collect());
                fmi2_outputs.push((index, dependencies));
            }
            b"ScalarVariable" => {
                let variable =
                    Open { attributes: a, kind: None, type_attributes: Attributes::new(), array: false, start: None };
                if empty {
                    finish(&mut d, variable, &mut positions, &mut fmi2_derivatives)?;
                } else {
                    open = Some(variable);
                }
            }
            b"Dimension" => {
                if let Some(o) = open.as_mut() {
                    o.array = true;
                }
            }
            b"Start" => {
                if let (Some(o), Some(v)) = (open.as_mut(), a.get("value")) {
                    o.start = Some(v.clone());
                }
            }
            element_name if !root => {
                return Err(format!("<{}> before <fmiModelDescription>", String::from_utf8_lossy(element_name)));
            }
            element_name => {
                if let Some(o) = open.as_mut().filter(|o| d.version == Version::Fmi2 && o.kind.is_none()) {
                    // FMI 2.0: the type element inside a ScalarVariable.
                    o.kind = fmi2_kind(element_name);
                    o.type_attributes = a;
                } else if d.version == Version::Fmi3
                    && (fmi3_kind(element_name).is_some() || element_name == b"Binary" || element_name == b"Clock")
                {
                    let variable = Open {
                        kind: fmi3_kind(element_name),
                        attributes: a,
                        type_attributes: Attributes::new(),
                        array: false,
                        start: None,
                    };
                    if empty {
                        finish(&mut d, variable, &mut positions, &mut fmi2_derivatives)?;
                    } else {
                        open = Some(variable);
                    }
                }
            }
        }
    }
    if !root {
        return Err("not an FMI model description (no <fmiModelDescription>)".into());
    }
    d.token = token.ok_or("no instantiationToken (3.0) or guid (2.0)")?;
    d.identifier = identifier.ok_or("not a co-simulation FMU (no <CoSimulation>)")?;
    if d.version == Version::Fmi2 {
        let vr_at = |index: usize| positions.get(index.wrapping_sub(1)).copied();
        for (k, of) in fmi2_derivatives {
            d.variables[k].derivative_of =
                Some(vr_at(of).ok_or_else(|| format!("{}: derivative {of} is no variable", d.variables[k].name))?);
        }
        for (index, dependencies) in fmi2_outputs {
            let vr = vr_at(index).ok_or_else(|| format!("<Outputs><Unknown index=\"{index}\"> is no variable"))?;
            d.outputs.push((vr, dependencies.map(|l| l.into_iter().filter_map(vr_at).collect())));
        }
    }
    Ok(d)
}

/// Adds a variable read whole to `d` (if it is a scalar of a kept
/// causality and type), noting FMI 2.0 positions and derivatives.
fn finish(
    d: &mut Description,
    open: Open,
    positions: &mut Vec<u32>,
    fmi2_derivatives: &mut Vec<(usize, usize)>,
) -> Result<(), String> {
    let a = &open.attributes;
    let name = a.get("name").cloned().ok_or("a variable without a name")?;
    let vr: u32 = a
        .get("valueReference")
        .and_then(|v| v.parse().ok())
        .ok_or_else(|| format!("{name}: no valueReference, or not a number"))?;
    positions.push(vr);
    let Some(causality) = causality(a.get("causality").map(String::as_str)) else { return Ok(()) };
    let Some(kind) = open.kind else {
        d.passed_over.push(format!("{name}: a type this importer does not read (Binary, Clock)"));
        return Ok(());
    };
    if open.array {
        d.passed_over.push(format!("{name}: an array (<Dimension>)"));
        return Ok(());
    }
    // FMI 3.0 puts start, unit and derivative on the variable, 2.0 on its type element.
    let get = |k: &str| a.get(k).or_else(|| open.type_attributes.get(k)).cloned();
    let start = open.start.clone().or_else(|| get("start"));
    let unit = get("unit").and_then(|u| known_unit(&u)).map_or("", |(name, _)| name);
    let derivative = get("derivative");
    let derivative_of = match (derivative, d.version) {
        (Some(v), Version::Fmi3) => {
            Some(v.parse().map_err(|_| format!("{name}: derivative {v:?} is not a value reference"))?)
        }
        (Some(v), Version::Fmi2) => {
            let index = v.parse().map_err(|_| format!("{name}: derivative {v:?} is not an index"))?;
            fmi2_derivatives.push((d.variables.len(), index));
            None
        }
        (None, _) => None,
    };
    d.variables.push(Declared {
        name,
        causality,
        kind,
        vr,
        start,
        unit,
        description: a.get("description").cloned().unwrap_or_default(),
        derivative_of,
        tunable: a.get("variability").is_some_and(|v| v == "tunable"),
    });
    Ok(())
}
