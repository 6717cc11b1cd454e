//! Options that the CLI and Python take by name: one list of names per option, so that
//! `--estimators` and Python's `estimators=` (or `--time-edges` and `time_edges=`) cannot
//! drift apart.

/// A render option whose values have names.
pub trait Named: Copy + PartialEq + 'static {
    /// Every value, in the order the names are listed.
    const ALL: &'static [Self];

    /// This value's name.
    fn name(self) -> &'static str;

    /// The value named `name`, if any (names are matched exactly).
    fn from_name(name: &str) -> Option<Self> {
        Self::ALL.iter().copied().find(|v| v.name() == name)
    }

    /// The names quoted and listed for a message: `"a", "b" or "c"`.
    fn listed() -> String {
        let names: Vec<String> = Self::ALL.iter().map(|v| format!("{:?}", v.name())).collect();
        match names.split_last() {
            Some((last, rest)) if !rest.is_empty() => format!("{} or {last}", rest.join(", ")),
            _ => names.concat(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Named;
    use crate::render::{BoundaryMode, TimeEdgeMode};

    /// Each value reads back from its name, and no two values share one.
    fn names_are_their_own<T: Named + std::fmt::Debug>() {
        for &v in T::ALL {
            assert_eq!(T::from_name(v.name()), Some(v), "{v:?}");
            assert_eq!(T::ALL.iter().filter(|o| o.name() == v.name()).count(), 1, "{v:?}");
        }
    }

    #[test]
    fn every_option_value_has_its_own_name() {
        names_are_their_own::<BoundaryMode>();
        names_are_their_own::<TimeEdgeMode>();
        assert_eq!(BoundaryMode::from_name("Full"), None);
        assert_eq!(
            BoundaryMode::listed(),
            r#""full", "interior", "boundary", "primary" or "secondary""#
        );
        assert_eq!(TimeEdgeMode::listed(), r#""auto" or "off""#);
    }
}
