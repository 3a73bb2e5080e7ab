//! Parameters of the mechanism (docs/model.md §1, §3, §4), defined once.
//!
//! The `parameters!` invocation below is the single definition of every parameter: it
//! generates the [`Parameters`] struct with its defaults, and the [`PARAMETERS`] table
//! (name, unit, description, rule) from which the FMI variable table, the model
//! description and the documentation are derived.

use super::ModelError;
use integrators::text::number;

/// What values a parameter admits; checked before a value is applied. Every rule bounds
/// the magnitude too: within these ranges every derived quantity (energies, accelerations,
/// the rod force) stays far from overflow, so no output can become infinite from finite
/// settings. The ranges are generous physically: a mechanism outside them is not this one.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Rule {
    /// |value| ≤ the bound.
    Finite(f64),
    /// Strictly positive, within [low, high] (lengths, inertias).
    Positive(f64, f64),
    /// Not negative, at most the bound (stiffnesses, dampers).
    NonNegative(f64),
}

/// Bounds of the rules (see [`Rule`]).
pub const MAX_INERTIA: f64 = 1e9;
pub const MIN_INERTIA: f64 = 1e-9;
pub const MAX_LENGTH: f64 = 1e3;
pub const MIN_LENGTH: f64 = 1e-6;
pub const MAX_STIFFNESS: f64 = 1e12;
pub const MAX_ANGLE: f64 = 1e6;
pub const MAX_SPEED: f64 = 1e6;
pub const MAX_TORQUE: f64 = 1e12;
/// The rule of the inputs M_m and M_r (torques, N·m).
pub const INPUT_RULE: Rule = Rule::Finite(MAX_TORQUE);

impl Rule {
    /// `Ok` when `value` satisfies the rule, else the rule in words.
    pub fn check(self, value: f64) -> Result<(), String> {
        if !value.is_finite() {
            return Err("must be a finite number".into());
        }
        match self {
            Rule::Finite(bound) if value.abs() > bound => Err(format!(
                "must be within ±{bound:e} (larger values overflow derived quantities)"
            )),
            Rule::Positive(..) if value <= 0.0 => Err("must be > 0".into()),
            Rule::Positive(low, high) if value < low || value > high => {
                Err(format!("must be in [{low:e}, {high:e}]"))
            }
            Rule::NonNegative(_) if value < 0.0 => Err("must be >= 0".into()),
            Rule::NonNegative(bound) if value > bound => Err(format!(
                "must be <= {bound:e} (larger values overflow derived quantities)"
            )),
            _ => Ok(()),
        }
    }

    /// The smallest and largest admitted values (the model description's min and max).
    pub fn range(self) -> (f64, f64) {
        match self {
            Rule::Finite(bound) => (-bound, bound),
            Rule::Positive(low, high) => (low, high),
            Rule::NonNegative(bound) => (0.0, bound),
        }
    }
}

/// Metadata of one parameter, in the order of the [`Parameters`] fields.
#[derive(Clone, Copy, Debug)]
pub struct ParamInfo {
    pub name: &'static str,
    pub unit: &'static str,
    pub default: f64,
    pub rule: Rule,
    pub description: &'static str,
}

macro_rules! parameters {
    ($($field:ident : $unit:literal, $default:expr, $rule:expr, $descr:literal;)*) => {
        /// Parameter values, by their FMI names (docs/model.md §1, §3, §4).
        #[allow(non_snake_case)]
        #[derive(Clone, Copy, Debug, PartialEq)]
        pub struct Parameters {
            $(#[doc = $descr] pub $field: f64,)*
            /// Whether the built-in motor and load laws (the coefficients `Mm_a*`, `Mr_b*`)
            /// add to the inputs M_m and M_r; off, the torques are the inputs alone, for
            /// external motor and load models (docs/model.md §4). The FMI Boolean
            /// parameter `builtin_laws`.
            pub builtin_laws: bool,
        }

        impl Default for Parameters {
            fn default() -> Self { Self { $($field: $default,)* builtin_laws: true } }
        }

        /// Every parameter's metadata, in field order: index `i` here is index `i` of
        /// [`Parameters::get`] and [`Parameters::set`].
        pub const PARAMETERS: &[ParamInfo] = &[
            $(ParamInfo { name: stringify!($field), unit: $unit, default: $default,
                          rule: $rule, description: $descr },)*
        ];

        impl Parameters {
            /// Value of parameter `index` (see [`PARAMETERS`]); `None` when out of range.
            pub fn get(&self, index: usize) -> Option<f64> {
                let values = [$(self.$field,)*];
                values.get(index).copied()
            }

            /// Mutable slot of parameter `index`; `None` when out of range.
            fn slot_mut(&mut self, index: usize) -> Option<&mut f64> {
                let slots = [$(&mut self.$field,)*];
                slots.into_iter().nth(index)
            }
        }
    };
}

parameters! {
    J1: "kg.m2", 0.5, Rule::Positive(MIN_INERTIA, MAX_INERTIA), "Inertia of body 1, the motor rotor";
    J2: "kg.m2", 0.2, Rule::Positive(MIN_INERTIA, MAX_INERTIA), "Inertia of body 2, the crank";
    J3: "kg.m2", 0.3, Rule::Positive(MIN_INERTIA, MAX_INERTIA), "Inertia of body 3, the rocker";
    J4: "kg.m2", 0.7, Rule::Positive(MIN_INERTIA, MAX_INERTIA), "Inertia of body 4, the load";
    k12: "N.m/rad", 100.0, Rule::NonNegative(MAX_STIFFNESS), "Stiffness of the torsional spring between bodies 1 and 2";
    k34: "N.m/rad", 100.0, Rule::NonNegative(MAX_STIFFNESS), "Stiffness of the torsional spring between bodies 3 and 4";
    d12: "N.m.s/rad", 0.0, Rule::NonNegative(MAX_STIFFNESS), "Viscous damper in parallel with spring k12";
    d34: "N.m.s/rad", 0.0, Rule::NonNegative(MAX_STIFFNESS), "Viscous damper in parallel with spring k34";
    c4: "N.m.s/rad", 0.0, Rule::NonNegative(MAX_STIFFNESS), "Viscous damper acting on body 4 against ground";
    l: "m", 0.5, Rule::Positive(MIN_LENGTH, MAX_LENGTH), "Distance between the crank pivot O2 and the rocker pivot O3";
    l2: "m", 0.05, Rule::Positive(MIN_LENGTH, MAX_LENGTH), "Crank radius |O2 A2|";
    l3: "m", 0.5, Rule::Positive(MIN_LENGTH, MAX_LENGTH), "Rocker radius |O3 A3|";
    L: "m", 0.7, Rule::Positive(MIN_LENGTH, MAX_LENGTH), "Length of the rigid rod A2 A3";
    phi2_0: "rad", 0.0, Rule::Finite(MAX_ANGLE), "Initial crank angle phi2(0)";
    phi3_guess: "rad", std::f64::consts::FRAC_PI_2, Rule::Finite(MAX_ANGLE),
        "Initial rocker angle guess: of the two assemblies, the one with phi3(0) nearest this is used";
    twist12_0: "rad", 0.0, Rule::Finite(MAX_ANGLE), "Initial spring twist: phi1(0) = phi2(0) + twist12_0";
    twist34_0: "rad", 0.0, Rule::Finite(MAX_ANGLE), "Initial spring twist: phi4(0) = phi3(0) - twist34_0";
    omega1_0: "rad/s", 0.0, Rule::Finite(MAX_SPEED), "Initial speed of body 1";
    omega2_0: "rad/s", 0.0, Rule::Finite(MAX_SPEED), "Initial speed of the crank; omega3(0) follows from the constraint";
    omega4_0: "rad/s", 0.0, Rule::Finite(MAX_SPEED), "Initial speed of body 4";
    Mm_a0: "N.m", 100.0, Rule::Finite(MAX_TORQUE), "Built-in motor law (while builtin_laws): M_m += Mm_a0 + Mm_a1*omega1 + Mm_a2*omega1^2; the paper's 100";
    Mm_a1: "N.m.s/rad", -20.0, Rule::Finite(MAX_TORQUE), "Built-in motor law, linear coefficient; the paper's -20";
    Mm_a2: "N.m.s2/rad2", -1.0, Rule::Finite(MAX_TORQUE), "Built-in motor law, quadratic coefficient; the paper's -1";
    Mr_b0: "N.m", 20.0, Rule::Finite(MAX_TORQUE), "Built-in load law (while builtin_laws): M_r += Mr_b0 + Mr_b1*omega1; the paper's 20";
    Mr_b1: "N.m.s/rad", -0.05, Rule::Finite(MAX_TORQUE), "Built-in load law, linear coefficient in omega1; the paper's -0.05";
}

impl Parameters {
    /// Set parameter `index` after checking its rule; on error nothing changes and the
    /// message names the parameter and the rule.
    pub fn set(&mut self, index: usize, value: f64) -> Result<(), ModelError> {
        let info = PARAMETERS
            .get(index)
            .ok_or_else(|| ModelError::new(format!("no parameter with index {index}")))?;
        check_rule(info, value)?;
        if let Some(slot) = self.slot_mut(index) {
            *slot = value;
        }
        Ok(())
    }

    /// Index of the parameter called `name`.
    pub fn index_of(name: &str) -> Option<usize> {
        PARAMETERS.iter().position(|p| p.name == name)
    }

    /// Set a parameter by name (for tests and Rust users).
    pub fn set_by_name(&mut self, name: &str, value: f64) -> Result<(), ModelError> {
        let index =
            Self::index_of(name).ok_or_else(|| ModelError::new(format!("no parameter {name}")))?;
        self.set(index, value)
    }

    /// The same parameters with the built-in laws off: the torques are the inputs alone
    /// (an external motor and load, or a free run) (docs/model.md §4).
    pub fn without_builtin_laws(mut self) -> Self {
        self.builtin_laws = false;
        self
    }

    /// Check every rule; the first violation is the error.
    pub fn validate(&self) -> Result<(), ModelError> {
        for (info, value) in PARAMETERS.iter().zip((0..).map_while(|i| self.get(i))) {
            check_rule(info, value)?;
        }
        Ok(())
    }
}

/// `Ok` when `value` satisfies the parameter's rule; the error names both.
pub fn check_rule(info: &ParamInfo, value: f64) -> Result<(), ModelError> {
    info.rule.check(value).map_err(|rule| {
        ModelError::new(format!(
            "parameter {} = {} {rule}",
            info.name,
            number(value)
        ))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_and_struct_agree() {
        let p = Parameters::default();
        for (i, info) in PARAMETERS.iter().enumerate() {
            assert_eq!(p.get(i), Some(info.default), "{}", info.name);
        }
        assert_eq!(p.get(PARAMETERS.len()), None);
        assert_eq!(p.J3, 0.3);
        assert_eq!(p.L, 0.7);
    }

    #[test]
    fn set_checks_rules_and_keeps_value_on_error() {
        let mut p = Parameters::default();
        let err = p.set_by_name("J2", -1.0).unwrap_err();
        assert!(
            err.to_string().contains("J2") && err.to_string().contains("> 0"),
            "{err}"
        );
        assert_eq!(p.J2, 0.2);
        let err = p.set_by_name("k12", f64::NAN).unwrap_err();
        assert!(err.to_string().contains("k12") && err.to_string().contains("finite"));
        assert!(p.set_by_name("k12", -1.0).is_err());
        p.set_by_name("k12", 0.0).unwrap();
        assert_eq!(p.k12, 0.0);
        p.set_by_name("phi2_0", -3.0).unwrap();
        assert_eq!(p.phi2_0, -3.0);
    }
}
