//! The one table of FMI variables. Value references are positions in [`variables`]:
//! inputs, outputs, the parameters of [`PARAMETERS`], then the solver statistics
//! (Integer outputs) and the solver choice (an Enumeration parameter). The FMI dispatch
//! (either version's getters and setters), both `modelDescription.xml` files, the documentation and the
//! README's table are all derived from here, so they cannot drift apart.

use crate::model::params::INPUT_RULE;
use crate::model::{Parameters, PARAMETERS, STATE_SIZE};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Causality {
    Input,
    Output,
    Parameter,
    Local,
}

impl Causality {
    pub fn as_str(self) -> &'static str {
        match self {
            Causality::Input => "input",
            Causality::Output => "output",
            Causality::Parameter => "parameter",
            Causality::Local => "local",
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

/// The loop's independent coordinates (docs/model.md §6): the continuous states of Model
/// Exchange, x = (φ1, q, φ4, ω1, q̇, ω4) with q = φ2 or φ3, and their derivatives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Local {
    /// q: φ2 in the crank chart, φ3 in the rocker chart.
    LoopAngle,
    /// q̇: ω2 or ω3.
    LoopSpeed,
    /// The time derivative of component i of x.
    Derivative(usize),
    /// Model Exchange's event indicator: the leading angle's handover function.
    HandoverIndicator,
}

/// An Enumeration parameter whose Integer twin a master that cannot set Enumerations
/// (libcosim, Ecos) sets instead. A twin holds 0 by default: the Enumeration decides. Any
/// other value is one of the Enumeration's items and decides instead, whatever the order
/// in which the two were set; a master that sets every start value sets the twin's 0.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Twin {
    Solver,
    ChangePointBranch,
    /// Of sensitivity slot k (0-based).
    SensitivityParameter(usize),
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
    Local(Local),
    /// Which angle q is: 2 (φ2) or 3 (φ3), an Integer local.
    LoopChart,
    /// Whether the built-in torque laws apply (a Boolean parameter).
    BuiltinLaws,
    /// The branch taken at a change point, one of [`BRANCHES`] (a tunable Enumeration
    /// parameter).
    ChangePointBranch,
    /// Which parameter sensitivity slot k (0-based) carries, one of
    /// [`crate::model::sensitivity::ITEMS`] (a fixed Enumeration parameter).
    SensitivityParameter(usize),
    /// ∂y_state/∂(slot's parameter) at the communication point (a Real local).
    Sensitivity {
        slot: usize,
        state: usize,
    },
    /// The Integer twin of an Enumeration parameter.
    Twin(Twin),
}

/// FMI base types used here.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VarType {
    Real,
    Integer,
    Enumeration,
    Boolean,
}

impl VarType {
    pub fn as_str(self) -> &'static str {
        match self {
            VarType::Real => "Real",
            VarType::Integer => "Integer",
            VarType::Enumeration => "Enumeration",
            VarType::Boolean => "Boolean",
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
/// The name of the change-point branches' type in the XML (items: [`BRANCHES`]).
pub const BRANCH_TYPE: &str = "ChangePointBranch";
pub use crate::model::change_point::{Branch, BRANCHES};
/// The name of the sensitivity slots' type in the XML (items: [`SENSITIVITY_ITEMS`]).
pub const SENSITIVITY_TYPE: &str = "SensitivityParameter";
pub use crate::model::sensitivity::{ITEMS as SENSITIVITY_ITEMS, SLOTS as SENSITIVITY_SLOTS};

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
            Slot::Parameter(_) | Slot::SolverChoice | Slot::BuiltinLaws => Causality::Parameter,
            Slot::ChangePointBranch | Slot::SensitivityParameter(_) => Causality::Parameter,
            Slot::Twin(_) => Causality::Parameter,
            Slot::Local(_) | Slot::LoopChart | Slot::Sensitivity { .. } => Causality::Local,
        }
    }

    pub fn var_type(&self) -> VarType {
        match self.slot {
            Slot::Statistic(Statistic::ActiveSolver) => VarType::Enumeration,
            Slot::Statistic(_) | Slot::LoopChart | Slot::Twin(_) => VarType::Integer,
            Slot::SolverChoice | Slot::LinkageClass => VarType::Enumeration,
            Slot::ChangePointBranch | Slot::SensitivityParameter(_) => VarType::Enumeration,
            Slot::BuiltinLaws => VarType::Boolean,
            _ => VarType::Real,
        }
    }

    /// FMI variability: parameters are fixed (settable before initialisation ends), but
    /// for the branch at a change point, which a master may choose at every event.
    pub fn variability(&self) -> &'static str {
        match self.slot {
            Slot::Parameter(_) | Slot::SolverChoice | Slot::BuiltinLaws => "fixed",
            Slot::SensitivityParameter(_) => "fixed",
            Slot::Twin(Twin::Solver | Twin::SensitivityParameter(_)) => "fixed",
            Slot::ChangePointBranch | Slot::Twin(Twin::ChangePointBranch) => "tunable",
            Slot::Statistic(_) | Slot::LinkageClass | Slot::LoopChart => "discrete",
            _ => "continuous",
        }
    }

    /// FMI `initial` attribute; inputs have none.
    pub fn initial(&self) -> Option<&'static str> {
        match self.causality() {
            Causality::Input => None,
            Causality::Output | Causality::Local => Some("calculated"),
            Causality::Parameter => Some("exact"),
        }
    }

    /// The values the FMU admits (the model description's min and max), where it checks.
    pub fn range(&self) -> Option<(f64, f64)> {
        match self.slot {
            Slot::Parameter(i) => Some(PARAMETERS[i].rule.range()),
            Slot::Input(_) => Some(INPUT_RULE.range()),
            Slot::SolverChoice => Some((SOLVER_ITEMS[0].1 as f64, SOLVER_ITEMS[2].1 as f64)),
            Slot::ChangePointBranch => Some((BRANCHES[0].1 as f64, BRANCHES[1].1 as f64)),
            Slot::SensitivityParameter(_) => {
                let last = SENSITIVITY_ITEMS[SENSITIVITY_ITEMS.len() - 1];
                Some((SENSITIVITY_ITEMS[0].1 as f64, last.1 as f64))
            }
            Slot::Twin(Twin::Solver) => Some((0.0, SOLVER_ITEMS[2].1 as f64)),
            Slot::Twin(Twin::ChangePointBranch) => Some((0.0, BRANCHES[1].1 as f64)),
            Slot::Twin(Twin::SensitivityParameter(_)) => {
                let last = SENSITIVITY_ITEMS[SENSITIVITY_ITEMS.len() - 1];
                Some((0.0, last.1 as f64))
            }
            Slot::Output(_) | Slot::Statistic(_) | Slot::LinkageClass => None,
            Slot::Local(_) | Slot::LoopChart | Slot::BuiltinLaws => None,
            Slot::Sensitivity { .. } => None,
        }
    }

    /// For a state derivative, the value reference of its state (`derivative` in the XML).
    pub fn derivative_of(&self) -> Option<u32> {
        match self.slot {
            Slot::Local(Local::Derivative(i)) => Some(STATE_REFERENCES[i]),
            _ => None,
        }
    }

    /// The declared type of an Enumeration variable.
    pub fn declared_type(&self) -> Option<&'static str> {
        match self.slot {
            Slot::SolverChoice | Slot::Statistic(Statistic::ActiveSolver) => Some(SOLVER_TYPE),
            Slot::LinkageClass => Some(LINKAGE_TYPE),
            Slot::ChangePointBranch => Some(BRANCH_TYPE),
            Slot::SensitivityParameter(_) => Some(SENSITIVITY_TYPE),
            _ => None,
        }
    }

    /// The start value, where the variable has one (Integer and Enumeration values are
    /// whole numbers; a Boolean's is 1 for true, 0 for false).
    pub fn start(&self) -> Option<f64> {
        match self.slot {
            Slot::Input(_) => Some(0.0),
            Slot::Output(_) | Slot::Statistic(_) | Slot::LinkageClass => None,
            Slot::Local(_) | Slot::LoopChart | Slot::Sensitivity { .. } => None,
            Slot::SensitivityParameter(_) | Slot::Twin(_) => Some(0.0),
            Slot::Parameter(i) => Some(PARAMETERS[i].default),
            Slot::SolverChoice => Some(SOLVER_ITEMS[0].1 as f64),
            Slot::BuiltinLaws => Some(f64::from(u8::from(Parameters::default().builtin_laws))),
            Slot::ChangePointBranch => Some(Branch::Straight as i32 as f64),
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

const fn local(
    name: &'static str,
    unit: &'static str,
    description: &'static str,
    which: Local,
) -> Variable {
    Variable {
        name,
        unit,
        description,
        slot: Slot::Local(which),
    }
}

/// The Model Exchange states and derivatives (docs/model.md §6); readable in both interfaces.
const EXCHANGE_VARIABLES: [Variable; 9] = [
    local(
        "loop_angle",
        "rad",
        "The loop's independent angle: phi2 or phi3, as loop_chart says (a Model Exchange state)",
        Local::LoopAngle,
    ),
    local(
        "loop_speed",
        "rad/s",
        "The loop's independent speed: omega2 or omega3, as loop_chart says (a Model Exchange state)",
        Local::LoopSpeed,
    ),
    Variable {
        name: "loop_chart",
        unit: "",
        description: "Which angle loop_angle is: 2 (phi2, the crank) or 3 (phi3, the rocker)",
        slot: Slot::LoopChart,
    },
    local("der(phi1)", "rad/s", "Time derivative of phi1", Local::Derivative(0)),
    local(
        "der(loop_angle)",
        "rad/s",
        "Time derivative of loop_angle",
        Local::Derivative(1),
    ),
    local("der(phi4)", "rad/s", "Time derivative of phi4", Local::Derivative(2)),
    local(
        "der(omega1)",
        "rad/s2",
        "Time derivative of omega1",
        Local::Derivative(3),
    ),
    local(
        "der(loop_speed)",
        "rad/s2",
        "Time derivative of loop_speed",
        Local::Derivative(4),
    ),
    local(
        "der(omega4)",
        "rad/s2",
        "Time derivative of omega4",
        Local::Derivative(5),
    ),
];

/// Variables added after the first release, last so that every earlier value reference
/// keeps its number.
const LATER_VARIABLES: [Variable; 3] = [
    Variable {
        name: "builtin_laws",
        unit: "",
        description: "Whether the built-in motor and load laws (Mm_a0..Mm_a2, Mr_b0, Mr_b1; the paper's by default) add to the inputs M_m and M_r; false for external motor and load models, whose torques are then the inputs alone",
        slot: Slot::BuiltinLaws,
    },
    local(
        "handover_indicator",
        "",
        "Model Exchange's event indicator: positive while loop_angle determines the loop, crossing zero where the other angle should lead (docs/model.md §6)",
        Local::HandoverIndicator,
    ),
    Variable {
        name: "change_point_branch",
        unit: "",
        description: "The branch a change-point linkage takes where crank, rod and rocker fall collinear: straight (1) or turn (2); used by FMI 3.0 Co-Simulation in event mode, where the step returns early at the change point (docs/model.md §7)",
        slot: Slot::ChangePointBranch,
    },
];

macro_rules! sensitivity_slot {
    ($k:literal) => {
        sensitivity_slot!($k, $k - 1,
            0 "phi1", 1 "phi2", 2 "phi3", 3 "phi4", 4 "omega1", 5 "omega2", 6 "omega3", 7 "omega4")
    };
    ($k:literal, $slot:expr, $($state:literal $name:literal),*) => {
        [
            Variable {
                name: concat!("sensitivity_", $k, ".parameter"),
                unit: "",
                description: concat!(
                    "The parameter whose sensitivities the sensitivity_", $k,
                    ".* locals carry (none: the slot is unused); Co-Simulation only (docs/sensitivities.md)"
                ),
                slot: Slot::SensitivityParameter($slot),
            },
            $(Variable {
                name: concat!("sensitivity_", $k, ".", $name),
                unit: "",
                description: concat!(
                    "Derivative of ", $name, " with respect to the parameter sensitivity_", $k,
                    ".parameter names, along the run since initialisation"
                ),
                slot: Slot::Sensitivity { slot: $slot, state: $state },
            },)*
        ]
    };
}

macro_rules! twin_of_slot {
    ($k:literal) => {
        Variable {
            name: concat!("sensitivity_", $k, ".parameter_code"),
            unit: "",
            description: concat!(
                "sensitivity_",
                $k,
                ".parameter as an Integer, for masters that cannot set ",
                "Enumerations: 0 (the default) leaves the choice to sensitivity_",
                $k,
                ".parameter; an item's value decides instead of it"
            ),
            slot: Slot::Twin(Twin::SensitivityParameter($k - 1)),
        }
    };
}

/// The sensitivity slots (docs/sensitivities.md): per slot, the parameter it follows and
/// the eight states' derivatives with respect to it.
const SENSITIVITY_VARIABLES: [[Variable; 1 + STATE_SIZE]; SENSITIVITY_SLOTS] = [
    sensitivity_slot!(1),
    sensitivity_slot!(2),
    sensitivity_slot!(3),
    sensitivity_slot!(4),
    sensitivity_slot!(5),
];

/// The Integer twins of the Enumeration parameters (see [`Twin`]), after every earlier
/// variable so that their value references keep their numbers.
const TWIN_VARIABLES: [Variable; 2 + SENSITIVITY_SLOTS] = [
    Variable {
        name: "solver_code",
        unit: "",
        description: "solver as an Integer, for masters that cannot set Enumerations: 0 (the default) leaves the choice to solver; auto (1), dop853 (2) or implicit (3) decides instead of it",
        slot: Slot::Twin(Twin::Solver),
    },
    Variable {
        name: "change_point_branch_code",
        unit: "",
        description: "change_point_branch as an Integer, for masters that cannot set Enumerations: 0 (the default) leaves the choice to change_point_branch; straight (1) or turn (2) decides instead of it",
        slot: Slot::Twin(Twin::ChangePointBranch),
    },
    twin_of_slot!(1),
    twin_of_slot!(2),
    twin_of_slot!(3),
    twin_of_slot!(4),
    twin_of_slot!(5),
];

/// Number of variables (and one past the largest value reference).
pub const COUNT: usize = INPUTS.len()
    + OUTPUTS.len()
    + PARAMETERS.len()
    + SOLVER_VARIABLES.len()
    + EXCHANGE_VARIABLES.len()
    + LATER_VARIABLES.len()
    + SENSITIVITY_VARIABLES.len() * (1 + STATE_SIZE)
    + TWIN_VARIABLES.len();

/// The value references of the Model Exchange states x = (φ1, q, φ4, ω1, q̇, ω4).
pub const STATE_REFERENCES: [u32; 6] = {
    let table = build_table();
    let mut refs = [0u32; 6];
    let mut vr = 0;
    while vr < COUNT {
        let index = match table[vr].slot {
            Slot::Output(Output::Angle(0)) => 0,
            Slot::Local(Local::LoopAngle) => 1,
            Slot::Output(Output::Angle(3)) => 2,
            Slot::Output(Output::Speed(0)) => 3,
            Slot::Local(Local::LoopSpeed) => 4,
            Slot::Output(Output::Speed(3)) => 5,
            _ => usize::MAX,
        };
        if index != usize::MAX {
            refs[index] = vr as u32;
        }
        vr += 1;
    }
    refs
};

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
    k = 0;
    while k < EXCHANGE_VARIABLES.len() {
        table[i] = EXCHANGE_VARIABLES[k];
        (i, k) = (i + 1, k + 1);
    }
    k = 0;
    while k < LATER_VARIABLES.len() {
        table[i] = LATER_VARIABLES[k];
        (i, k) = (i + 1, k + 1);
    }
    k = 0;
    while k < SENSITIVITY_VARIABLES.len() * (1 + STATE_SIZE) {
        table[i] = SENSITIVITY_VARIABLES[k / (1 + STATE_SIZE)][k % (1 + STATE_SIZE)];
        (i, k) = (i + 1, k + 1);
    }
    k = 0;
    while k < TWIN_VARIABLES.len() {
        table[i] = TWIN_VARIABLES[k];
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

/// How an unknown depends on a known (ModelStructure's `dependenciesKind`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// A factor of 1: the unknown is the known (a state's derivative that is a state).
    Constant,
    /// A factor of fixed parameters only (linear in the known).
    Fixed,
    /// Any other dependence.
    Dependent,
}

impl Kind {
    pub fn as_str(self) -> &'static str {
        match self {
            Kind::Constant => "constant",
            Kind::Fixed => "fixed",
            Kind::Dependent => "dependent",
        }
    }
}

/// The unknowns of ModelStructure: which list, hence which knowns.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Unknowns {
    /// Outputs and state derivatives while running: the knowns are the inputs and the Model
    /// Exchange states (in Co-Simulation only the inputs apply).
    Running,
    /// At initialisation: the knowns are the inputs and the parameters.
    Initial,
}

/// The Model Exchange states' names, in the order of x.
pub const STATES: [&str; 6] = [
    "phi1",
    "loop_angle",
    "phi4",
    "omega1",
    "loop_speed",
    "omega4",
];

/// Which knowns each unknown depends on directly, from the equations (docs/model.md §2,
/// §3, §6), with how: the `dependencies` and `dependenciesKind` of ModelStructure.
/// While running, no output feels an input directly: the torques act on bodies 1 and 4,
/// which reach the loop (and λ, the rod force) only through springs and dampers; only
/// the accelerations der(omega1) and der(omega4) feel them.
pub fn dependencies(unknown: &Variable, list: Unknowns) -> Vec<(&'static str, Kind)> {
    let mut pairs = match list {
        Unknowns::Running => running_dependencies(unknown.slot),
        Unknowns::Initial => initial_dependencies(unknown.slot)
            .into_iter()
            .map(|name| (name, Kind::Dependent))
            .collect(),
    };
    pairs.sort_by_key(|(n, _)| value_reference(n).expect("a variable of the table"));
    pairs
}

/// Whether a variable is an unknown of `list` (listed in ModelStructure there).
pub fn is_unknown(v: &Variable, list: Unknowns) -> bool {
    match (v.slot, list) {
        (Slot::Local(Local::Derivative(_)), _) => true,
        // An event indicator, listed as such (FMI 3.0), not among the initial unknowns.
        (Slot::Local(Local::HandoverIndicator), _) => false,
        (Slot::Local(_), Unknowns::Initial) => true,
        _ => v.causality() == Causality::Output,
    }
}

fn running_dependencies(slot: Slot) -> Vec<(&'static str, Kind)> {
    use Kind::*;
    let states = |kind: Kind| STATES.iter().map(|s| (*s, kind)).collect::<Vec<_>>();
    // By slot, exhaustively: a new variable must say what it depends on.
    match slot {
        Slot::Output(Output::Angle(0)) => vec![("phi1", Constant)],
        Slot::Output(Output::Angle(3)) => vec![("phi4", Constant)],
        Slot::Output(Output::Angle(_)) | Slot::Output(Output::ConstraintResidual) => {
            vec![("loop_angle", Dependent)]
        }
        Slot::Output(Output::Speed(0)) => vec![("omega1", Constant)],
        Slot::Output(Output::Speed(3)) => vec![("omega4", Constant)],
        Slot::Output(Output::Speed(_)) => {
            vec![("loop_angle", Dependent), ("loop_speed", Dependent)]
        }
        Slot::Output(Output::Energy) | Slot::Output(Output::RodForce) => states(Dependent),
        Slot::Local(Local::Derivative(0)) => vec![("omega1", Constant)],
        Slot::Local(Local::Derivative(1)) => vec![("loop_speed", Constant)],
        Slot::Local(Local::Derivative(2)) => vec![("omega4", Constant)],
        // J1·ω̇1 = M_m + motor law(ω1) + k12·(φ2 − φ1) + d12·(ω2 − ω1).
        Slot::Local(Local::Derivative(3)) => vec![
            ("M_m", Fixed),
            ("phi1", Fixed),
            ("loop_angle", Dependent),
            ("omega1", Dependent),
            ("loop_speed", Dependent),
        ],
        // The loop feels everything but the torques.
        Slot::Local(Local::Derivative(4)) => states(Dependent),
        // J4·ω̇4 = k34·(φ3 − φ4) + d34·(ω3 − ω4) − M_r − load law(ω1) − c4·ω4.
        Slot::Local(Local::Derivative(_)) => vec![
            ("M_r", Fixed),
            ("loop_angle", Dependent),
            ("phi4", Fixed),
            ("omega1", Fixed),
            ("loop_speed", Dependent),
            ("omega4", Fixed),
        ],
        // Integer and Enumeration outputs change only at steps and events.
        Slot::Statistic(_) | Slot::LinkageClass => vec![],
        // The leading angle's handover function: of the configuration alone.
        Slot::Local(Local::HandoverIndicator) => vec![("loop_angle", Dependent)],
        // Not unknowns while running.
        Slot::Local(_) | Slot::LoopChart => vec![],
        Slot::Input(_) | Slot::Parameter(_) | Slot::SolverChoice | Slot::BuiltinLaws => vec![],
        Slot::ChangePointBranch | Slot::SensitivityParameter(_) | Slot::Twin(_) => vec![],
        // Locals that are not unknowns: a run's history, not a function of the knowns.
        Slot::Sensitivity { .. } => vec![],
    }
}

/// The lengths and the assembly's inputs: what φ3(0) (and so the geometry) depends on.
const ASSEMBLY: &[&str] = &["l", "l2", "l3", "L", "phi2_0", "phi3_guess"];
const INERTIAS_AND_SPRINGS: &[&str] = &["J1", "J2", "J3", "J4", "k12", "k34"];
const START_SPEEDS: &[&str] = &["omega1_0", "omega2_0", "omega4_0"];
const TWISTS: &[&str] = &["twist12_0", "twist34_0"];
/// What the loop's bodies 2 and 3 feel, besides their own geometry and states: their
/// inertias, the springs and dampers that tie them to bodies 1 and 4.
const LOOP_FORCES: &[&str] = &["J2", "J3", "k12", "k34", "d12", "d34"];
const MOTOR: &[&str] = &[
    "M_m",
    "J1",
    "k12",
    "d12",
    "Mm_a0",
    "Mm_a1",
    "Mm_a2",
    "builtin_laws",
];
const LOAD: &[&str] = &[
    "M_r",
    "J4",
    "k34",
    "d34",
    "c4",
    "Mr_b0",
    "Mr_b1",
    "builtin_laws",
];

fn initial_dependencies(slot: Slot) -> Vec<&'static str> {
    match slot {
        Slot::Output(Output::Angle(0)) => vec!["phi2_0", "twist12_0"],
        Slot::Output(Output::Angle(1)) => vec!["phi2_0"],
        Slot::Output(Output::Angle(3)) => [ASSEMBLY, &["twist34_0"]].concat(),
        Slot::Output(Output::Angle(_)) | Slot::Output(Output::ConstraintResidual) => {
            ASSEMBLY.to_vec()
        }
        Slot::Output(Output::Speed(0)) | Slot::Local(Local::Derivative(0)) => vec!["omega1_0"],
        Slot::Output(Output::Speed(1)) => vec!["omega2_0"],
        Slot::Output(Output::Speed(3)) | Slot::Local(Local::Derivative(2)) => vec!["omega4_0"],
        Slot::Output(Output::Speed(_)) => [ASSEMBLY, &["omega2_0"]].concat(),
        Slot::Output(Output::Energy) => {
            [ASSEMBLY, INERTIAS_AND_SPRINGS, START_SPEEDS, TWISTS].concat()
        }
        Slot::Output(Output::RodForce) | Slot::Local(Local::Derivative(4)) => {
            [ASSEMBLY, LOOP_FORCES, START_SPEEDS, TWISTS].concat()
        }
        // Which angle leads depends on the assembly; φ2 or φ3 then as above.
        Slot::Local(Local::LoopAngle) | Slot::Local(Local::HandoverIndicator) => ASSEMBLY.to_vec(),
        Slot::Local(Local::LoopSpeed) | Slot::Local(Local::Derivative(1)) => {
            [ASSEMBLY, &["omega2_0"]].concat()
        }
        // φ2 − φ1 = −twist12_0, ω1 and ω2 as set.
        Slot::Local(Local::Derivative(3)) => {
            [MOTOR, &["omega1_0", "omega2_0", "twist12_0"]].concat()
        }
        // φ3 − φ4 = twist34_0; ω3 from the assembly; the load law reads ω1.
        Slot::Local(Local::Derivative(_)) => [
            LOAD,
            ASSEMBLY,
            &["omega1_0", "omega2_0", "omega4_0", "twist34_0"],
        ]
        .concat(),
        Slot::Statistic(Statistic::ActiveSolver) => vec!["solver", "solver_code"],
        // The step counters: zero until the first step.
        Slot::Statistic(_) => vec![],
        Slot::LinkageClass => vec!["l", "l2", "l3", "L"],
        Slot::LoopChart => ASSEMBLY.to_vec(),
        // Not unknowns: knowns.
        Slot::Input(_) | Slot::Parameter(_) | Slot::SolverChoice | Slot::BuiltinLaws => vec![],
        Slot::ChangePointBranch | Slot::SensitivityParameter(_) | Slot::Twin(_) => vec![],
        // Locals that are not unknowns: a run's history, not a function of the knowns.
        Slot::Sensitivity { .. } => vec![],
    }
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
    ("rad/s2", [0, 0, -2, 1]),
    // Time, FMI 3.0's independent variable.
    ("s", [0, 0, 1, 0]),
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

    /// Every unit a Real variable names is defined (a dimensionless one names none).
    #[test]
    fn every_unit_is_defined() {
        let defined: HashSet<_> = UNITS.iter().map(|(u, _)| *u).collect();
        let real = |v: &Variable| v.var_type() == VarType::Real && !v.unit.is_empty();
        for (_, v) in variables().filter(|(_, v)| real(v)) {
            assert!(
                defined.contains(v.unit),
                "{} has undefined unit {}",
                v.name,
                v.unit
            );
        }
    }
}
