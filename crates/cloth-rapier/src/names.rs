//! Nearest names for errors about unknown joints, links and bodies: a
//! misspelt name is reported with the names it was probably meant to be.

use cloth_core::FieldError;

/// At most this many suggestions.
const SUGGESTIONS: usize = 3;

/// The names in `known` nearest to `name` (Damerau-Levenshtein similarity,
/// ignoring case), at most three, nearest first; ties in `known`'s order.
pub(crate) fn nearest<'a>(name: &str, known: impl IntoIterator<Item = &'a str>) -> Vec<&'a str> {
    let wanted = name.to_lowercase();
    let mut scored: Vec<(f64, usize, &str)> = known
        .into_iter()
        .enumerate()
        .map(|(k, n)| (strsim::normalized_damerau_levenshtein(&wanted, &n.to_lowercase()), k, n))
        .collect();
    scored.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    scored.into_iter().take(SUGGESTIONS).map(|(_, _, n)| n).collect()
}

/// `no <what> "<name>" (nearest: "a", "b", "c")`, or without the
/// parenthesis when nothing is known.
pub(crate) fn unknown<'a>(what: &str, name: &str, known: impl IntoIterator<Item = &'a str>) -> String {
    let near = nearest(name, known);
    if near.is_empty() {
        return format!("no {what} {name:?}");
    }
    let list: Vec<String> = near.iter().map(|n| format!("{n:?}")).collect();
    format!("no {what} {name:?} (nearest: {})", list.join(", "))
}

/// Problems as one error: none, the one as it is, or several under
/// `group` as `field: problem; field: problem`.
pub(crate) fn combined(problems: Vec<FieldError>, group: impl Into<String>) -> Option<FieldError> {
    match problems.len() {
        0 => None,
        1 => problems.into_iter().next(),
        _ => {
            let all: Vec<String> = problems.iter().map(FieldError::to_string).collect();
            Some(FieldError::new(group, all.join("; ")))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_misspelt_name_gets_the_names_it_resembles() {
        let links = ["pelvis", "thigh_l", "thigh_r", "shin_l", "shin_r", "torso"];
        assert_eq!(nearest("thig_l", links), vec!["thigh_l", "thigh_r", "shin_l"]);
        assert_eq!(nearest("Pelvis", links)[0], "pelvis");
        assert_eq!(unknown("link", "torsoo", links).split(" (nearest").next(), Some("no link \"torsoo\""));
        assert!(unknown("link", "torsoo", links).contains("\"torso\""));
        assert_eq!(unknown("link", "x", std::iter::empty()), "no link \"x\"");
    }
}
