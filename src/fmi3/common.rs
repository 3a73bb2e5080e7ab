//! The functions both interfaces share, after instantiation (`instantiation.rs`): modes,
//! values, FMU states, directional and adjoint derivatives, discrete states, and the
//! families of functions this FMU has no variables or features for, each refused with its
//! reason.

use fmi_sys::fmi3::*;

use super::{check_value_count, export, references, table_reference, table_references, Accessor};
use crate::abi::{self, null_argument, slice, slice_mut};
use crate::instance::{Failure, Instance, Outcome};
use crate::plant::Value;
use crate::variables::VarType;

/// The FMU state functions' argument names, for the messages.
const STATE_NAMES: abi::StateNames = abi::StateNames {
    state: "FMUState",
    size_function: "fmi3SerializedFMUStateSize",
};

export! {
    /// # Safety
    /// `instance` is an instance; `categories` must hold `nCategories` valid C strings.
    fn fmi3SetDebugLogging(
        instance,
        loggingOn: fmi3Boolean,
        nCategories: usize,
        categories: *const fmi3String,
    ): fmi3SetDebugLoggingTYPE = |instance| {
        // SAFETY: FMI contract on `categories`.
        let names = unsafe { abi::category_names(categories, nCategories) }?;
        instance.set_debug_logging(loggingOn, &names)
    };
}

export! {
    /// # Safety
    /// `instance` is an instance.
    fn fmi3EnterInitializationMode(
        instance,
        toleranceDefined: fmi3Boolean,
        tolerance: fmi3Float64,
        startTime: fmi3Float64,
        stopTimeDefined: fmi3Boolean,
        stopTime: fmi3Float64,
    ): fmi3EnterInitializationModeTYPE = |instance| {
        let tolerance = toleranceDefined.then_some(tolerance);
        let stop = stopTimeDefined.then_some(stopTime);
        instance.setup_experiment(tolerance, startTime, stop)?;
        instance.enter_initialization_mode()
    };
}

export! {
    /// # Safety
    /// `instance` is an instance.
    fn fmi3ExitInitializationMode(instance): fmi3ExitInitializationModeTYPE =
        Instance::exit_initialization_mode;
}

export! {
    /// # Safety
    /// `instance` is an instance.
    fn fmi3EnterEventMode(instance): fmi3EnterEventModeTYPE = Instance::enter_event_mode;
}

export! {
    /// # Safety
    /// `instance` is an instance.
    fn fmi3Terminate(instance): fmi3TerminateTYPE = Instance::terminate;
}

export! {
    /// # Safety
    /// `instance` is an instance.
    fn fmi3Reset(instance): fmi3ResetTYPE = Instance::reset;
}

export! {
    /// # Safety
    /// `instance` is an instance; `valueReferences` and `values` must hold
    /// `nValueReferences` elements.
    fn fmi3GetFloat64(
        instance,
        valueReferences: *const fmi3ValueReference,
        nValueReferences: usize,
        values: *mut fmi3Float64,
        nValues: usize,
    ): fmi3GetFloat64TYPE = |instance| {
        check_value_count(nValueReferences, nValues)?;
        // SAFETY: FMI contract on the arrays.
        let vrs = unsafe { references(valueReferences, nValueReferences) }?;
        // SAFETY: FMI contract on the arrays.
        let values = unsafe { slice_mut(values, nValues) }
            .ok_or_else(|| null_argument("values", nValues))?;
        for (&vr, value) in vrs.iter().zip(values.iter_mut()) {
            match table_reference(vr, Accessor::Float64)? {
                None => *value = instance.last_successful_time(),
                Some(table) => instance.get_real(&[table], std::slice::from_mut(value))?,
            }
        }
        Ok(())
    };
}

/// A getter of FMI 3.0's Int32, Int64 (enumerations) or Boolean: the table's Integer or
/// Boolean values, each converted to the C type by `$to`.
macro_rules! whole_getter {
    ($name:ident: $check:ident, $ctype:ty, $accessor:ident, $read:ident, $to:expr) => {
        export! {
            /// # Safety
            /// `instance` is an instance; `valueReferences` and `values` must hold
            /// `nValueReferences` elements.
            fn $name(
                instance,
                valueReferences: *const fmi3ValueReference,
                nValueReferences: usize,
                values: *mut $ctype,
                nValues: usize,
            ): $check = |instance| {
                check_value_count(nValueReferences, nValues)?;
                // SAFETY: FMI contract on the arrays.
                let vrs = unsafe { references(valueReferences, nValueReferences) }?;
                // SAFETY: FMI contract on the arrays.
                let values = unsafe { slice_mut(values, nValues) }
                    .ok_or_else(|| null_argument("values", nValues))?;
                let table = table_references(vrs, Accessor::$accessor)?;
                instance.get_whole(table, VarType::$read, |i, v| values[i] = $to(v))
            };
        }
    };
}

whole_getter!(fmi3GetInt32: fmi3GetInt32TYPE, fmi3Int32, Int32, Integer, |v| v);
whole_getter!(fmi3GetInt64: fmi3GetInt64TYPE, fmi3Int64, Int64, Integer, i64::from);
whole_getter!(fmi3GetBoolean: fmi3GetBooleanTYPE, fmi3Boolean, Boolean, Boolean, |v| v != 0);

/// A setter of FMI 3.0's Float64, Int32, Int64 (enumerations) or Boolean: each C value
/// becomes a [`Value`] through `$value`, after `$admit` has checked it (every value and
/// reference is checked before any is set).
macro_rules! setter {
    ($name:ident: $check:ident, $ctype:ty, $accessor:ident, $admit:expr, $value:expr) => {
        export! {
            /// # Safety
            /// `instance` is an instance; `valueReferences` and `values` must hold
            /// `nValueReferences` elements.
            fn $name(
                instance,
                valueReferences: *const fmi3ValueReference,
                nValueReferences: usize,
                values: *const $ctype,
                nValues: usize,
            ): $check = |instance| {
                check_value_count(nValueReferences, nValues)?;
                // SAFETY: FMI contract on the arrays.
                let vrs = unsafe { references(valueReferences, nValueReferences) }?;
                // SAFETY: FMI contract on the arrays.
                let values = unsafe { slice(values, nValues) }
                    .ok_or_else(|| null_argument("values", nValues))?;
                let table = table_references(vrs, Accessor::$accessor)?;
                for (v, vr) in values.iter().zip(vrs) {
                    $admit(*v, *vr)?;
                }
                instance.set_values(table.zip(values.iter().map(|v| $value(*v))))
            };
        }
    };
}

/// Every value of the type is one a variable may take a value of.
fn any<T>(_: T, _: u32) -> Outcome {
    Ok(())
}

/// An enumeration's value: the FMU's items are small whole numbers.
fn enumeration_item(v: i64, vr: u32) -> Outcome {
    i32::try_from(v).map(drop).map_err(|_| {
        Failure::error(format!(
            "value reference {vr} = {v}: not an item of its enumeration"
        ))
    })
}

setter!(fmi3SetFloat64: fmi3SetFloat64TYPE, fmi3Float64, Float64, any, Value::Real);
setter!(fmi3SetInt32: fmi3SetInt32TYPE, fmi3Int32, Int32, any, Value::Integer);
// Admitted by `enumeration_item` first, so the conversion keeps the value.
setter!(fmi3SetInt64: fmi3SetInt64TYPE, fmi3Int64, Int64, enumeration_item, |v: i64| {
    Value::Integer(v as i32)
});
setter!(fmi3SetBoolean: fmi3SetBooleanTYPE, fmi3Boolean, Boolean, any, Value::Boolean);

/// An access of a type no variable of this FMU has: any value reference is unknown; an
/// empty request succeeds.
fn no_variables_of(type_name: &str, vrs: &[u32]) -> Outcome {
    match vrs.first() {
        None => Ok(()),
        Some(vr) => Err(Failure::error(format!(
            "no {type_name} variable has value reference {vr} (this FMU's variables are \
             Float64, Int32, Boolean and Enumerations, read and written as Int64)"
        ))),
    }
}

/// Getters and setters of the types this FMU has no variables of.
macro_rules! no_variables {
    ($($name:ident: $check:ident, $type_name:literal, ($($arg:ident: $ty:ty),*);)*) => {
        $(export! {
            /// # Safety
            /// `instance` is an instance; `valueReferences` must hold `nValueReferences`
            /// elements.
            fn $name(
                instance,
                valueReferences: *const fmi3ValueReference,
                nValueReferences: usize,
                $($arg: $ty),*
            ): $check = |_| {
                // SAFETY: FMI contract on the array.
                let vrs = unsafe { references(valueReferences, nValueReferences) }?;
                no_variables_of($type_name, vrs)
            };
        })*
    };
}

no_variables! {
    fmi3GetFloat32: fmi3GetFloat32TYPE, "Float32", (_values: *mut fmi3Float32, _nValues: usize);
    fmi3GetInt8: fmi3GetInt8TYPE, "Int8", (_values: *mut fmi3Int8, _nValues: usize);
    fmi3GetUInt8: fmi3GetUInt8TYPE, "UInt8", (_values: *mut fmi3UInt8, _nValues: usize);
    fmi3GetInt16: fmi3GetInt16TYPE, "Int16", (_values: *mut fmi3Int16, _nValues: usize);
    fmi3GetUInt16: fmi3GetUInt16TYPE, "UInt16", (_values: *mut fmi3UInt16, _nValues: usize);
    fmi3GetUInt32: fmi3GetUInt32TYPE, "UInt32", (_values: *mut fmi3UInt32, _nValues: usize);
    fmi3GetUInt64: fmi3GetUInt64TYPE, "UInt64", (_values: *mut fmi3UInt64, _nValues: usize);
    fmi3GetString: fmi3GetStringTYPE, "String", (_values: *mut fmi3String, _nValues: usize);
    fmi3GetBinary: fmi3GetBinaryTYPE, "Binary",
        (_valueSizes: *mut usize, _values: *mut fmi3Binary, _nValues: usize);
    fmi3GetClock: fmi3GetClockTYPE, "Clock", (_values: *mut fmi3Clock);
    fmi3SetFloat32: fmi3SetFloat32TYPE, "Float32", (_values: *const fmi3Float32, _nValues: usize);
    fmi3SetInt8: fmi3SetInt8TYPE, "Int8", (_values: *const fmi3Int8, _nValues: usize);
    fmi3SetUInt8: fmi3SetUInt8TYPE, "UInt8", (_values: *const fmi3UInt8, _nValues: usize);
    fmi3SetInt16: fmi3SetInt16TYPE, "Int16", (_values: *const fmi3Int16, _nValues: usize);
    fmi3SetUInt16: fmi3SetUInt16TYPE, "UInt16", (_values: *const fmi3UInt16, _nValues: usize);
    fmi3SetUInt32: fmi3SetUInt32TYPE, "UInt32", (_values: *const fmi3UInt32, _nValues: usize);
    fmi3SetUInt64: fmi3SetUInt64TYPE, "UInt64", (_values: *const fmi3UInt64, _nValues: usize);
    fmi3SetString: fmi3SetStringTYPE, "String", (_values: *const fmi3String, _nValues: usize);
    fmi3SetBinary: fmi3SetBinaryTYPE, "Binary",
        (_valueSizes: *const usize, _values: *const fmi3Binary, _nValues: usize);
    fmi3SetClock: fmi3SetClockTYPE, "Clock", (_values: *const fmi3Clock);
    fmi3GetIntervalDecimal: fmi3GetIntervalDecimalTYPE, "Clock",
        (_intervals: *mut fmi3Float64, _qualifiers: *mut fmi3IntervalQualifier);
    fmi3GetIntervalFraction: fmi3GetIntervalFractionTYPE, "Clock",
        (_counters: *mut fmi3UInt64, _resolutions: *mut fmi3UInt64,
         _qualifiers: *mut fmi3IntervalQualifier);
    fmi3GetShiftDecimal: fmi3GetShiftDecimalTYPE, "Clock", (_shifts: *mut fmi3Float64);
    fmi3GetShiftFraction: fmi3GetShiftFractionTYPE, "Clock",
        (_counters: *mut fmi3UInt64, _resolutions: *mut fmi3UInt64);
    fmi3SetIntervalDecimal: fmi3SetIntervalDecimalTYPE, "Clock", (_intervals: *const fmi3Float64);
    fmi3SetIntervalFraction: fmi3SetIntervalFractionTYPE, "Clock",
        (_counters: *const fmi3UInt64, _resolutions: *const fmi3UInt64);
    fmi3SetShiftDecimal: fmi3SetShiftDecimalTYPE, "Clock", (_shifts: *const fmi3Float64);
    fmi3SetShiftFraction: fmi3SetShiftFractionTYPE, "Clock",
        (_counters: *const fmi3UInt64, _resolutions: *const fmi3UInt64);
}

/// Functions of features the FMU does not declare, refused with the flag or reason.
macro_rules! refused {
    ($($name:ident: $check:ident, ($($arg:ident: $ty:ty),*) => $reason:literal;)*) => {
        $(export! {
            /// # Safety
            /// `instance` is an instance (no other argument is read).
            fn $name(instance $(, $arg: $ty)*): $check = |_| Err(Failure::error($reason));
        })*
    };
}

refused! {
    fmi3GetNumberOfVariableDependencies: fmi3GetNumberOfVariableDependenciesTYPE,
        (_valueReference: fmi3ValueReference, _nDependencies: *mut usize) =>
        "providesPerElementDependencies is false: the dependencies are those of \
         modelDescription.xml's ModelStructure";
    fmi3GetVariableDependencies: fmi3GetVariableDependenciesTYPE,
        (_dependent: fmi3ValueReference, _elementIndicesOfDependent: *mut usize,
         _independents: *mut fmi3ValueReference, _elementIndicesOfIndependents: *mut usize,
         _dependencyKinds: *mut fmi3DependencyKind, _nDependencies: usize) =>
        "providesPerElementDependencies is false: the dependencies are those of \
         modelDescription.xml's ModelStructure";
    fmi3EnterConfigurationMode: fmi3EnterConfigurationModeTYPE, () =>
        "this FMU has no structural parameters, so no configuration mode";
    fmi3ExitConfigurationMode: fmi3ExitConfigurationModeTYPE, () =>
        "this FMU has no structural parameters, so no configuration mode";
    fmi3EvaluateDiscreteStates: fmi3EvaluateDiscreteStatesTYPE, () =>
        "providesEvaluateDiscreteStates is false: this FMU has no clocked discrete states";
    fmi3ActivateModelPartition: fmi3ActivateModelPartitionTYPE,
        (_clockReference: fmi3ValueReference, _activationTime: fmi3Float64) =>
        "this FMU provides Model Exchange and Co-Simulation, not Scheduled Execution";
}

export! {
    /// # Safety
    /// `instance` is an instance; the flags must be NULL or writable.
    fn fmi3UpdateDiscreteStates(
        instance,
        discreteStatesNeedUpdate: *mut fmi3Boolean,
        terminateSimulation: *mut fmi3Boolean,
        nominalsOfContinuousStatesChanged: *mut fmi3Boolean,
        valuesOfContinuousStatesChanged: *mut fmi3Boolean,
        nextEventTimeDefined: *mut fmi3Boolean,
        nextEventTime: *mut fmi3Float64,
    ): fmi3UpdateDiscreteStatesTYPE = |instance| {
        let changed = instance.update_discrete_states()?;
        // SAFETY: NULL or writable by the FMI contract; a NULL flag is not wanted.
        unsafe {
            let flags = [
                (discreteStatesNeedUpdate, false),
                (terminateSimulation, false),
                (nominalsOfContinuousStatesChanged, false),
                (valuesOfContinuousStatesChanged, changed),
                (nextEventTimeDefined, false),
            ];
            for (pointer, value) in flags {
                if let Some(flag) = pointer.as_mut() {
                    *flag = value;
                }
            }
            if let Some(time) = nextEventTime.as_mut() {
                *time = 0.0;
            }
        }
        Ok(())
    };
}

export! {
    /// # Safety
    /// `instance` is an instance; `FMUState` must be NULL or point to a writable pointer (NULL, or
    /// a state of `instance`).
    fn fmi3GetFMUState(instance, FMUState: *mut fmi3FMUState): fmi3GetFMUStateTYPE = |instance| {
        // SAFETY: FMI contract on the pointer.
        unsafe { abi::get_fmu_state(instance, FMUState, &STATE_NAMES) }
    };
}

export! {
    /// # Safety
    /// `instance` is an instance.
    fn fmi3SetFMUState(instance, FMUState: fmi3FMUState): fmi3SetFMUStateTYPE = |instance| {
        instance.restore_issued(FMUState)
    };
}

export! {
    /// # Safety
    /// `instance` is an instance; `FMUState` must be NULL or point to a writable pointer.
    fn fmi3FreeFMUState(instance, FMUState: *mut fmi3FMUState): fmi3FreeFMUStateTYPE = |instance| {
        // SAFETY: FMI contract on the pointer.
        unsafe { abi::free_fmu_state(instance, FMUState) }
    };
}

export! {
    /// # Safety
    /// `instance` is an instance; `size` must be NULL or writable.
    fn fmi3SerializedFMUStateSize(instance, FMUState: fmi3FMUState, size: *mut usize):
        fmi3SerializedFMUStateSizeTYPE = |instance| {
        // SAFETY: FMI contract on the pointer.
        unsafe { abi::serialized_size(instance, FMUState, size) }
    };
}

export! {
    /// # Safety
    /// `instance` is an instance; `serializedState` must hold `size` writable bytes.
    fn fmi3SerializeFMUState(
        instance,
        FMUState: fmi3FMUState,
        serializedState: *mut fmi3Byte,
        size: usize,
    ): fmi3SerializeFMUStateTYPE = |instance| {
        // SAFETY: FMI contract on the buffer.
        unsafe { abi::serialize(instance, FMUState, serializedState.cast(), size, &STATE_NAMES) }
    };
}

export! {
    /// # Safety
    /// `instance` is an instance; `serializedState` must hold `size` readable bytes; `FMUState`
    /// must be NULL or point to a writable pointer (NULL, or a state of `instance`).
    fn fmi3DeserializeFMUState(
        instance,
        serializedState: *const fmi3Byte,
        size: usize,
        FMUState: *mut fmi3FMUState,
    ): fmi3DeserializeFMUStateTYPE = |instance| {
        // SAFETY: FMI contract on the buffer and the pointer.
        unsafe {
            abi::deserialize(instance, serializedState.cast(), size, FMUState, &STATE_NAMES)
        }
    };
}

/// Which product a derivative function gives: J·seed (directional; the seed per known, the
/// sensitivity per unknown) or Jᵀ·seed (adjoint; the other way round).
#[derive(Clone, Copy, PartialEq)]
enum Product {
    Directional,
    Adjoint,
}

/// The four arrays of a derivative function, their lengths checked for `product`, the
/// references translated to the variable table's, and the product computed.
///
/// # Safety
/// FMI contract on the four arrays with their lengths.
unsafe fn derivative(
    instance: &mut Instance,
    product: Product,
    (unknowns, n_unknowns): (*const fmi3ValueReference, usize),
    (knowns, n_knowns): (*const fmi3ValueReference, usize),
    (seed, n_seed): (*const fmi3Float64, usize),
    (sensitivity, n_sensitivity): (*mut fmi3Float64, usize),
) -> Outcome {
    let (per_seed, per_sensitivity) = match product {
        Product::Directional => (("nKnowns", n_knowns), ("nUnknowns", n_unknowns)),
        Product::Adjoint => (("nUnknowns", n_unknowns), ("nKnowns", n_knowns)),
    };
    check_lengths("nSeed", n_seed, per_seed)?;
    check_lengths("nSensitivity", n_sensitivity, per_sensitivity)?;
    // SAFETY: FMI contract on the arrays.
    let (u, k, s, d) = unsafe {
        (
            slice(unknowns, n_unknowns),
            slice(knowns, n_knowns),
            slice(seed, n_seed),
            slice_mut(sensitivity, n_sensitivity),
        )
    };
    let u = u.ok_or_else(|| null_argument("unknowns", n_unknowns))?;
    let k = k.ok_or_else(|| null_argument("knowns", n_knowns))?;
    let s = s.ok_or_else(|| null_argument("seed", n_seed))?;
    let d = d.ok_or_else(|| null_argument("sensitivity", n_sensitivity))?;
    let u: Vec<u32> = table_references(u, Accessor::Float64)?.collect();
    let k: Vec<u32> = table_references(k, Accessor::Float64)?.collect();
    match product {
        Product::Directional => instance.directional_derivative(&u, &k, s, d),
        Product::Adjoint => instance.adjoint_derivative(&u, &k, s, d),
    }
}

fn check_lengths(what: &str, n: usize, (of, expected): (&str, usize)) -> Outcome {
    if n != expected {
        return Err(Failure::error(format!(
            "{what} = {n} must equal {of} = {expected} (this FMU has no array variables)"
        )));
    }
    Ok(())
}

/// fmi3GetDirectionalDerivative and fmi3GetAdjointDerivative: one signature, two products.
macro_rules! derivative_function {
    ($name:ident: $check:ident, $product:ident) => {
        export! {
            /// # Safety
            /// `instance` is an instance; the arrays must hold the numbers of elements given.
            fn $name(
                instance,
                unknowns: *const fmi3ValueReference,
                nUnknowns: usize,
                knowns: *const fmi3ValueReference,
                nKnowns: usize,
                seed: *const fmi3Float64,
                nSeed: usize,
                sensitivity: *mut fmi3Float64,
                nSensitivity: usize,
            ): $check = |instance| {
                // SAFETY: FMI contract on the arrays.
                unsafe {
                    derivative(
                        instance,
                        Product::$product,
                        (unknowns, nUnknowns),
                        (knowns, nKnowns),
                        (seed, nSeed),
                        (sensitivity, nSensitivity),
                    )
                }
            };
        }
    };
}

derivative_function!(fmi3GetDirectionalDerivative: fmi3GetDirectionalDerivativeTYPE, Directional);
derivative_function!(fmi3GetAdjointDerivative: fmi3GetAdjointDerivativeTYPE, Adjoint);
