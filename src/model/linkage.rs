//! The class of the four-bar (Grashof's criterion): which links can turn fully, and so
//! which motions the linkage allows. The links are the ground l (O2 O3), the crank l2,
//! the rod L and the rocker l3; s and g are the shortest and the longest, p and q the
//! other two.

use super::Parameters;

/// The classes, as the `linkage_class` output gives them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LinkageClass {
    CrankRocker = 1,
    DoubleCrank = 2,
    DoubleRocker = 3,
    RockerCrank = 4,
    TripleRocker = 5,
    ChangePoint = 6,
}

/// Name, value and description of each class: the enumeration type of the output.
pub const LINKAGE_CLASSES: [(&str, i32, &str); 6] = [
    ("crank_rocker", 1, "Grashof, the crank shortest: the crank turns fully, the rocker swings"),
    ("double_crank", 2, "Grashof, the ground shortest: crank and rocker both turn fully"),
    ("double_rocker", 3, "Grashof, the rod shortest: crank and rocker both swing; the rod turns fully relative to them"),
    ("rocker_crank", 4, "Grashof, the rocker shortest: the rocker turns fully, the crank swings"),
    ("triple_rocker", 5, "non-Grashof (s + g > p + q): no link turns fully; crank and rocker swing back at their dead points"),
    ("change_point", 6, "s + g = p + q: crank, rod and rocker can fall collinear, where the motion is not determined (an event in FMI 3.0 Co-Simulation with event mode, where change_point_branch says how it goes on; refused otherwise)"),
];

/// Sums of link lengths closer than this, relative to their size, are taken as equal.
const EQUAL: f64 = 1e-12;

pub fn classify(p: &Parameters) -> LinkageClass {
    let mut links = [p.l, p.l2, p.l3, p.L];
    links.sort_by(f64::total_cmp);
    let [s, a, b, g] = links;
    let (extremes, others) = (s + g, a + b);
    if (extremes - others).abs() <= EQUAL * (extremes + others) {
        return LinkageClass::ChangePoint;
    }
    if extremes > others {
        return LinkageClass::TripleRocker;
    }
    // Grashof: the shortest link turns fully relative to the others.
    if s == p.l2 {
        LinkageClass::CrankRocker
    } else if s == p.l {
        LinkageClass::DoubleCrank
    } else if s == p.L {
        LinkageClass::DoubleRocker
    } else {
        LinkageClass::RockerCrank
    }
}

impl LinkageClass {
    pub fn name(self) -> &'static str {
        LINKAGE_CLASSES[self as usize - 1].0
    }

    pub fn description(self) -> &'static str {
        LINKAGE_CLASSES[self as usize - 1].2
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn class(l: f64, l2: f64, l3: f64, rod: f64) -> LinkageClass {
        classify(&Parameters {
            l,
            l2,
            l3,
            L: rod,
            ..Default::default()
        })
    }

    #[test]
    fn each_class() {
        assert_eq!(class(0.5, 0.05, 0.5, 0.7), LinkageClass::CrankRocker); // the defaults
        assert_eq!(class(0.1, 0.4, 0.45, 0.5), LinkageClass::DoubleCrank);
        assert_eq!(class(0.5, 0.4, 0.45, 0.15), LinkageClass::DoubleRocker);
        assert_eq!(class(0.5, 0.4, 0.1, 0.45), LinkageClass::RockerCrank);
        assert_eq!(class(0.5, 0.05, 0.5, 0.96), LinkageClass::TripleRocker);
        assert_eq!(class(0.5, 0.05, 0.5, 0.95), LinkageClass::ChangePoint);
        for (i, (_, value, _)) in LINKAGE_CLASSES.iter().enumerate() {
            assert_eq!(*value as usize, i + 1);
        }
    }
}
