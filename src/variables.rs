//! The one table of FMI variables. Value references are positions in [`variables`]:
//! inputs, outputs, the parameters of [`PARAMETERS`], then the solver statistics
//! (Integer outputs) and the solver choice (an Enumeration parameter). The FMI dispatch
//! (`fmi2GetReal`/`fmi2SetReal`), `modelDescription.xml`, the documentation and the
//! README's table are all derived from here, so they cannot drift apart.

use crate::model::params::INPUT_RULE;
use crate::model::PARAMETERS;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Causality {
    Input,
    Output,
    Parameter,
}

impl Causality {
    pub fn as_str(self) -> &'static str {
        match self {
            Causality::Input => "input",
            Causality::Output => "output",
            Causality::Parameter => "parameter",
        }
    }
}

/// The FMU inputs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Input {
    MotorTorque,
    LoadTorque,
}

/// The FMU outputs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Output {
    /// φ_i, i = 0..3.
    Angle(usize),
    /// ω_i, i = 0..3.
    Speed(usize),
    RodForce,
    ConstraintResidual,
    Energy,
}

/// Cumulative solver statistics since initialisation (Integer outputs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Statistic {
    Steps,
    Rejected,
    RightHandSides,
    /// The method integrating now (2 = dop853, 3 = implicit): what `auto` chose.
    ActiveSolver,
}

/// Where a variable's value lives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Slot {
    Input(Input),
    Output(Output),
    /// Index into [`PARAMETERS`].
    Parameter(usize),
    Statistic(Statistic),
    /// The `solver` parameter, one of [`SOLVER_ITEMS`].
    SolverChoice,
    /// The linkage's class, one of [`LINKAGE_CLASSES`] (an Enumeration output).
    LinkageClass,
}

/// FMI base types used here.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VarType {
    Real,
    Integer,
    Enumeration,
}

impl VarType {
    pub fn as_str(self) -> &'static str {
        match self {
            VarType::Real => "Real",
            VarType::Integer => "Integer",
            VarType::Enumeration => "Enumeration",
        }
    }
}

/// The `solver` enumeration: name, value, description. The name of its type in the XML is
/// [`SOLVER_TYPE`].
pub const SOLVER_ITEMS: [(&str, i32, &str); 3] = [
    (
        "auto",
        1,
        "dop853, switching to implicit while a stiffness test finds the step limited by stability",
    ),
    (
        "dop853",
        2,
        "Explicit Runge-Kutta 8(5,3) of Dormand and Prince, for non-stiff settings",
    ),
    (
        "implicit",
        3,
        "Radau IIA of order 5 (implicit), for stiff springs and dampers",
    ),
];
pub const SOLVER_TYPE: &str = "SolverKind";
/// The name of the linkage classes' type in the XML (items: [`LINKAGE_CLASSES`]).
pub const LINKAGE_TYPE: &str = "LinkageClass";

/// One FMI variable.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Variable {
    pub name: &'static str,
    pub unit: &'static str,
    pub description: &'static str,
    pub slot: Slot,
}

impl Variable {
    pub fn causality(&self) -> Causality {
        match self.slot {
            Slot::Input(_) => Causality::Input,
            Slot::Output(_) | Slot::Statistic(_) | Slot::LinkageClass => Causality::Output,
            Slot::Parameter(_) | Slot::SolverChoice => Causality::Parameter,
        }
    }

    pub fn var_type(&self) -> VarType {
        match self.slot {
            Slot::Statistic(Statistic::ActiveSolver) => VarType::Enumeration,
            Slot::Statistic(_) => VarType::Integer,
            Slot::SolverChoice | Slot::LinkageClass => VarType::Enumeration,
            _ => VarType::Real,
        }
    }

    /// FMI variability: parameters are fixed (settable before initialisation ends).
    pub fn variability(&self) -> &'static str {
        match self.slot {
            Slot::Parameter(_) | Slot::SolverChoice => "fixed",
            Slot::Statistic(_) | Slot::LinkageClass => "discrete",
            _ => "continuous",
        }
    }

    /// FMI `initial` attribute; inputs have none.
    pub fn initial(&self) -> Option<&'static str> {
        match self.causality() {
            Causality::Input => None,
            Causality::Output => Some("calculated"),
            Causality::Parameter => Some("exact"),
        }
    }

    /// The values the FMU admits (the model description's min and max), where it checks.
    pub fn range(&self) -> Option<(f64, f64)> {
        match self.slot {
            Slot::Parameter(i) => Some(PARAMETERS[i].rule.range()),
            Slot::Input(_) => Some(INPUT_RULE.range()),
            Slot::SolverChoice => Some((SOLVER_ITEMS[0].1 as f64, SOLVER_ITEMS[2].1 as f64)),
            Slot::Output(_) | Slot::Statistic(_) | Slot::LinkageClass => None,
        }
    }

    /// The declared type of an Enumeration variable.
    pub fn declared_type(&self) -> Option<&'static str> {
        match self.slot {
            Slot::SolverChoice | Slot::Statistic(Statistic::ActiveSolver) => Some(SOLVER_TYPE),
            Slot::LinkageClass => Some(LINKAGE_TYPE),
            _ => None,
        }
    }

    /// The start value, where the variable has one (Integer and Enumeration values are
    /// whole numbers).
    pub fn start(&self) -> Option<f64> {
        match self.slot {
            Slot::Input(_) => Some(0.0),
            Slot::Output(_) | Slot::Statistic(_) | Slot::LinkageClass => None,
            Slot::Parameter(i) => Some(PARAMETERS[i].default),
            Slot::SolverChoice => Some(SOLVER_ITEMS[0].1 as f64),
        }
    }
}

const INPUTS: [Variable; 2] = [
    Variable {
        name: "M_m",
        unit: "N.m",
        description: "Motor torque on body 1, added to the built-in motor law",
        slot: Slot::Input(Input::MotorTorque),
    },
    Variable {
        name: "M_r",
        unit: "N.m",
        description: "Load torque resisting body 4, added to the built-in load law",
        slot: Slot::Input(Input::LoadTorque),
    },
];

const fn output(
    name: &'static str,
    unit: &'static str,
    description: &'static str,
    which: Output,
) -> Variable {
    Variable {
        name,
        unit,
        description,
        slot: Slot::Output(which),
    }
}

const OUTPUTS: [Variable; 11] = [
    output(
        "phi1",
        "rad",
        "Angle of body 1, the motor rotor",
        Output::Angle(0),
    ),
    output(
        "phi2",
        "rad",
        "Angle of body 2, the crank",
        Output::Angle(1),
    ),
    output(
        "phi3",
        "rad",
        "Angle of body 3, the rocker",
        Output::Angle(2),
    ),
    output("phi4", "rad", "Angle of body 4, the load", Output::Angle(3)),
    output("omega1", "rad/s", "Speed of body 1", Output::Speed(0)),
    output("omega2", "rad/s", "Speed of body 2", Output::Speed(1)),
    output("omega3", "rad/s", "Speed of body 3", Output::Speed(2)),
    output("omega4", "rad/s", "Speed of body 4", Output::Speed(3)),
    output(
        "rod_force",
        "N",
        "Axial force in the rod A2A3, tension positive",
        Output::RodForce,
    ),
    output(
        "constraint_residual",
        "m",
        "Loop closure error |A2A3| - L",
        Output::ConstraintResidual,
    ),
    output(
        "energy",
        "J",
        "Kinetic energy plus spring energy (conserved without torques and dampers)",
        Output::Energy,
    ),
];

const SOLVER_VARIABLES: [Variable; 6] = [
    Variable {
        name: "n_steps",
        unit: "",
        description: "Accepted integration steps since initialisation",
        slot: Slot::Statistic(Statistic::Steps),
    },
    Variable {
        name: "n_rejected",
        unit: "",
        description: "Rejected integration steps since initialisation",
        slot: Slot::Statistic(Statistic::Rejected),
    },
    Variable {
        name: "n_rhs",
        unit: "",
        description: "Right-hand-side evaluations since initialisation",
        slot: Slot::Statistic(Statistic::RightHandSides),
    },
    Variable {
        name: "solver",
        unit: "",
        description: "Integration method: auto (1), dop853 (2), implicit (3)",
        slot: Slot::SolverChoice,
    },
    Variable {
        name: "active_solver",
        unit: "",
        description: "Method integrating now: dop853 (2) or implicit (3); what auto chose",
        slot: Slot::Statistic(Statistic::ActiveSolver),
    },
    Variable {
        name: "linkage_class",
        unit: "",
        description: "The four-bar's class from l, l2, l3, L (Grashof): crank_rocker (1), double_crank (2), double_rocker (3), rocker_crank (4), triple_rocker (5), change_point (6)",
        slot: Slot::LinkageClass,
    },
];

/// Number of variables (and one past the largest value reference).
pub const COUNT: usize = INPUTS.len() + OUTPUTS.len() + PARAMETERS.len() + SOLVER_VARIABLES.len();

/// The table itself, built at compile time: position = value reference.
static TABLE: [Variable; COUNT] = build_table();

pub(crate) const fn build_table() -> [Variable; COUNT] {
    let mut table = [INPUTS[0]; COUNT];
    let mut i = 0;
    while i < INPUTS.len() {
        table[i] = INPUTS[i];
        i += 1;
    }
    let mut k = 0;
    while k < OUTPUTS.len() {
        table[i] = OUTPUTS[k];
        (i, k) = (i + 1, k + 1);
    }
    k = 0;
    while k < PARAMETERS.len() {
        let info = &PARAMETERS[k];
        table[i] = Variable {
            name: info.name,
            unit: info.unit,
            description: info.description,
            slot: Slot::Parameter(k),
        };
        (i, k) = (i + 1, k + 1);
    }
    k = 0;
    while k < SOLVER_VARIABLES.len() {
        table[i] = SOLVER_VARIABLES[k];
        (i, k) = (i + 1, k + 1);
    }
    table
}

/// Number of variables (and one past the largest value reference).
pub fn count() -> usize {
    COUNT
}

/// The variable with value reference `vr`.
#[inline]
pub fn variable(vr: u32) -> Option<&'static Variable> {
    TABLE.get(vr as usize)
}

/// All variables, with their value references, in value-reference order.
pub fn variables() -> impl Iterator<Item = (u32, Variable)> {
    (0..count() as u32).filter_map(|vr| Some((vr, *variable(vr)?)))
}

/// The value reference of the variable called `name`.
pub fn value_reference(name: &str) -> Option<u32> {
    variables().find(|(_, v)| v.name == name).map(|(vr, _)| vr)
}

/// The lengths and the assembly's inputs: what φ3(0) (and so the geometry) depends on.
const ASSEMBLY: &[&str] = &["l", "l2", "l3", "L", "phi2_0", "phi3_guess"];
const INERTIAS_AND_SPRINGS: &[&str] = &["J1", "J2", "J3", "J4", "k12", "k34"];
const START_SPEEDS: &[&str] = &["omega1_0", "omega2_0", "omega4_0"];
const TWISTS: &[&str] = &["twist12_0", "twist34_0"];
/// What the loop's bodies 2 and 3 feel, besides their own geometry and states: their
/// inertias, the springs and dampers that tie them to bodies 1 and 4.
const LOOP_FORCES: &[&str] = &["J2", "J3", "k12", "k34", "d12", "d34"];

/// Which knowns each output depends on directly, from the equations (docs/model.md §2, §3): the
/// `dependencies` of ModelStructure. At communication points (`Outputs`) the knowns are
/// the inputs, and no output feels them without integrating: the torques act on bodies 1
/// and 4, which reach the loop (and λ, the rod force) only through springs and dampers.
/// At initialisation (`InitialUnknowns`) the knowns also include the parameters.
pub fn dependencies(output: &Variable, initial: bool) -> Vec<&'static str> {
    if !initial {
        return vec![];
    }
    // By slot, exhaustively: a new variable must say what it depends on.
    let mut names: Vec<&str> = match output.slot {
        Slot::Output(Output::Angle(0)) => vec!["phi2_0", "twist12_0"],
        Slot::Output(Output::Angle(1)) => vec!["phi2_0"],
        Slot::Output(Output::Angle(3)) => [ASSEMBLY, &["twist34_0"]].concat(),
        Slot::Output(Output::Angle(_)) | Slot::Output(Output::ConstraintResidual) => {
            ASSEMBLY.to_vec()
        }
        Slot::Output(Output::Speed(0)) => vec!["omega1_0"],
        Slot::Output(Output::Speed(1)) => vec!["omega2_0"],
        Slot::Output(Output::Speed(3)) => vec!["omega4_0"],
        Slot::Output(Output::Speed(_)) => [ASSEMBLY, &["omega2_0"]].concat(),
        Slot::Output(Output::Energy) => {
            [ASSEMBLY, INERTIAS_AND_SPRINGS, START_SPEEDS, TWISTS].concat()
        }
        Slot::Output(Output::RodForce) => [ASSEMBLY, LOOP_FORCES, START_SPEEDS, TWISTS].concat(),
        Slot::Statistic(Statistic::ActiveSolver) => vec!["solver"],
        // The step counters: zero until the first step.
        Slot::Statistic(_) => vec![],
        Slot::LinkageClass => vec!["l", "l2", "l3", "L"],
        // Not unknowns: knowns.
        Slot::Input(_) | Slot::Parameter(_) | Slot::SolverChoice => vec![],
    };
    names.sort_by_key(|n| value_reference(n).expect("a variable of the table"));
    names
}

/// The units used by the variables, each with its SI base-unit exponents
/// (kg, m, s, rad), for `<UnitDefinitions>`.
pub const UNITS: &[(&str, [i32; 4])] = &[
    ("rad", [0, 0, 0, 1]),
    ("rad/s", [0, 0, -1, 1]),
    ("N", [1, 1, -2, 0]),
    ("N.m", [1, 2, -2, 0]),
    ("J", [1, 2, -2, 0]),
    ("m", [0, 1, 0, 0]),
    ("kg.m2", [1, 2, 0, 0]),
    ("N.m/rad", [1, 2, -2, -1]),
    ("N.m.s/rad", [1, 2, -1, -1]),
    ("N.m.s2/rad2", [1, 2, 0, -2]),
];

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashSet;

    #[test]
    fn names_are_unique_and_references_dense() {
        let names: HashSet<_> = variables().map(|(_, v)| v.name).collect();
        assert_eq!(names.len(), count());
        assert_eq!(variables().count(), count());
        assert!(variable(count() as u32).is_none());
        assert!(variable(u32::MAX).is_none());
    }

    #[test]
    fn issue_names_present_with_causality() {
        for name in ["M_m", "M_r"] {
            assert_eq!(
                variable(value_reference(name).unwrap())
                    .unwrap()
                    .causality(),
                Causality::Input
            );
        }
        for name in [
            "phi1",
            "phi4",
            "omega1",
            "omega4",
            "rod_force",
            "constraint_residual",
            "energy",
        ] {
            assert_eq!(
                variable(value_reference(name).unwrap())
                    .unwrap()
                    .causality(),
                Causality::Output
            );
        }
        for name in [
            "J1",
            "k34",
            "d12",
            "c4",
            "L",
            "phi3_guess",
            "omega4_0",
            "Mm_a2",
            "Mr_b1",
        ] {
            assert_eq!(
                variable(value_reference(name).unwrap())
                    .unwrap()
                    .causality(),
                Causality::Parameter
            );
        }
    }

    #[test]
    fn every_unit_is_defined() {
        let defined: HashSet<_> = UNITS.iter().map(|(u, _)| *u).collect();
        for (_, v) in variables().filter(|(_, v)| v.var_type() == VarType::Real) {
            assert!(
                defined.contains(v.unit),
                "{} has undefined unit {}",
                v.name,
                v.unit
            );
        }
    }
}
