use super::*;
use serde_json::json;
use std::path::Path;

fn mechanism() -> Description {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../modelDescription");
    Description::read(&root).unwrap()
}

fn spec(table: Value, metrics: Value) -> CycleSpec {
    serde_json::from_value(json!({"table": table, "metrics": metrics})).unwrap()
}

fn resolved(spec: &CycleSpec, d: &Description) -> Result<CyclePlan, Vec<(String, String)>> {
    let mut refusals = Refusals::default();
    CyclePlan::resolve(spec, d, &mut refusals)
        .ok_or_else(|| refusals.0.into_iter().map(|r| (r.field, r.rule)).collect())
}

const TAU: f64 = std::f64::consts::TAU;

#[test]
fn resolves_the_states_and_reads() {
    let table = json!({"state": "loop_angle", "advance": TAU, "shifted": ["phi1"],
                       "keep": ["omega2", "phi3"]});
    let metrics = json!([{"variable": "rod_force", "kind": "harmonic", "order": 2},
                         {"variable": "omega2", "kind": "mean"}]);
    let plan = resolved(&spec(table, metrics), &mechanism()).unwrap();
    assert_eq!((plan.state, plan.shifted.as_slice()), (1, &[0][..]));
    assert!(matches!(plan.way, Way::Exchange(Monodromy::Variational)));
    assert_eq!(plan.way.interface(), Interface::ModelExchange);
    assert_eq!(plan.reads.names, ["rod_force", "omega2", "phi3"]);
    // A kept variable read for a metric too is kept from the metric's slot.
    assert_eq!(plan.kept, [1, 2]);
    assert_eq!(plan.metrics[0].order, 2);
    assert_eq!(plan.names()[1], "loop_angle");
}

#[test]
fn refuses_every_mistake_by_its_field_at_once() {
    let d = mechanism();
    let table = json!({"state": "phi2", "advance": 0.0, "shifted": ["phi9", "phi1", "phi1"],
                       "monodromy": "exact", "samples": 4, "keep": ["linkage_class"],
                       "period": 6.5, "sampels": 9});
    let metrics = json!([{"field": "outputs.metrics.a", "variable": "rod_force", "kind": "harmonic"},
                         {"field": "outputs.metrics.b", "variable": "rod_force", "kind": "max", "order": 1},
                         {"field": "outputs.metrics.c", "variable": "rod_force", "kind": "final"},
                         {"field": "outputs.metrics.d", "variable": "rod_force", "kind": "max", "from": 2.0},
                         {"field": "outputs.metrics.e", "variable": "rod_force", "kind": "max", "extremes": "exact"}]);
    let refused = resolved(&spec(table, metrics), &d).unwrap_err();
    let said = |field: &str| -> String {
        let found: Vec<&String> = refused
            .iter()
            .filter(|(f, _)| f == field)
            .map(|(_, r)| r)
            .collect();
        assert_eq!(found.len(), 1, "{field} in {refused:?}");
        found[0].clone()
    };
    assert!(said("cycle.advance").starts_with("must be > 0"));
    assert!(said("cycle.monodromy").starts_with("must be \"variational\" or"));
    assert!(said("cycle.samples").contains("whole number in [8, 1048576]"));
    assert!(said("cycle.period").contains("called advance now"));
    assert!(said("cycle.sampels").contains("did you mean samples"));
    assert!(said("cycle.state").contains("not a continuous state"));
    assert!(said("cycle.state").contains("loop_angle"));
    assert!(said("cycle.shifted[0]").contains("no variable"));
    assert!(said("cycle.shifted[2]").contains("named twice"));
    assert!(said("cycle.keep[0]").contains("of type Enumeration"));
    assert!(said("outputs.metrics.a.order").starts_with("a harmonic needs"));
    assert!(said("outputs.metrics.b.order").starts_with("only a harmonic"));
    assert!(said("outputs.metrics.c.kind").contains("over a steady cycle"));
    assert!(said("outputs.metrics.d.from").contains("no window"));
    assert!(said("outputs.metrics.e.extremes").contains("\"sampled\""));
    let linearise = CycleSpec {
        linearise: true,
        ..spec(json!({"state": "loop_angle", "advance": 1.0}), json!([]))
    };
    let refused = resolved(&linearise, &d).unwrap_err();
    assert_eq!(refused[0].0, "cycle.modes");
    let mut without = d.clone();
    without.has_model_exchange = false;
    let refused = resolved(
        &spec(json!({"state": "loop_angle", "advance": 1.0}), json!([])),
        &without,
    )
    .unwrap_err();
    assert!(refused[0].1.contains("Model Exchange"), "{refused:?}");
    without = d.clone();
    without.exchange_directional_derivatives = false;
    let plan = resolved(
        &spec(json!({"state": "loop_angle", "advance": 1.0}), json!([])),
        &without,
    )
    .unwrap();
    assert!(matches!(plan.way, Way::Exchange(Monodromy::Differences)));
}

/// The Co-Simulation way's spec, as fmusweep writes it from the FMU's offer.
fn through(starts: &[&str], extra: Value) -> CycleSpec {
    let closing = [
        "phi1", "phi2", "phi3", "phi4", "omega1", "omega2", "omega3", "omega4",
    ];
    let slots: Vec<Value> = (1..=starts.len())
        .map(|k| json!([format!("sensitivity_{k}.parameter"), 7]))
        .collect();
    let columns: Vec<Vec<String>> = (1..=starts.len())
        .map(|k| {
            closing
                .iter()
                .map(|c| format!("sensitivity_{k}.{c}"))
                .collect()
        })
        .collect();
    let mut table = json!({"state": "phi2", "advance": TAU, "shifted": ["phi1"]});
    if let (Some(table), Some(extra)) = (table.as_object_mut(), extra.as_object()) {
        table.extend(extra.clone());
    }
    serde_json::from_value(json!({
        "table": table, "metrics": [],
        "starts": {"parameters": starts, "slots": slots, "closing": closing, "columns": columns}
    }))
    .unwrap()
}

const STARTS: [&str; 5] = ["twist12_0", "twist34_0", "omega1_0", "omega2_0", "omega4_0"];

#[test]
fn resolves_the_start_values_and_the_closing_variables() {
    let d = mechanism();
    let plan = resolved(&through(&STARTS, json!({"modes": 4})), &d).unwrap();
    let Way::Starts(starts) = &plan.way else {
        panic!("through the start values");
    };
    assert_eq!(plan.way.interface(), Interface::CoSimulation);
    assert_eq!((plan.state, plan.shifted.as_slice()), (1, &[0][..]));
    assert_eq!(plan.names()[1], "phi2");
    let vr = |name: &str| d.variable(name).unwrap().value_reference;
    assert_eq!(starts.parameters.vrs[0], vr("twist12_0"));
    assert_eq!(starts.closing.vrs[7], vr("omega4"));
    assert_eq!(starts.columns[4][1], vr("sensitivity_5.phi2"));
    assert_eq!(starts.slots[2], vr("sensitivity_3.parameter"));
    // The modes are Model Exchange's, read along the cycle.
    assert_eq!(plan.exchange.states.vrs.len(), 6);
}

#[test]
fn refuses_every_mistake_of_the_start_values_at_once() {
    let d = mechanism();
    let refused = |spec: CycleSpec, d: &Description| resolved(&spec, d).unwrap_err();
    let mut wrong = through(
        &["twist12_0", "twist12_0", "J9", "omega2_0"],
        json!({"monodromy": "variational", "state": "loop_angle"}),
    );
    wrong.metrics = vec![];
    let said = refused(wrong, &d);
    let fields: Vec<&str> = said.iter().map(|(f, _)| f.as_str()).collect();
    for expected in [
        "cycle.starts",
        "cycle.monodromy",
        "cycle.starts[1]",
        "cycle.starts[2]",
        "cycle.state",
    ] {
        assert!(fields.contains(&expected), "{expected} in {said:?}");
    }
    assert!(said
        .iter()
        .any(|(f, r)| f == "cycle.starts" && r.contains("5 free coordinates")));
    let mut without = d.clone();
    without.model_identifier = None;
    let said = refused(through(&STARTS, json!({})), &without);
    assert!(
        said[0]
            .1
            .starts_with("the cycle through the start values runs"),
        "{said:?}"
    );
    without = d.clone();
    without.exchange_directional_derivatives = false;
    let said = refused(through(&STARTS, json!({"modes": 2})), &without);
    assert_eq!(said[0].0, "cycle.modes", "{said:?}");
}

/// The fields a refusal of an unknown one lists as those the reader knows.
fn known_by_the_reader(refused: &[(String, String)], field: &str) -> Vec<String> {
    let (_, rule) = refused
        .iter()
        .find(|(f, _)| f == field)
        .unwrap_or_else(|| panic!("{field} not refused in {refused:?}"));
    let listed = rule
        .split_once("(the fields are: ")
        .and_then(|(_, rest)| rest.strip_suffix(')'))
        .unwrap_or_else(|| panic!("no list of fields in {rule:?}"));
    let mut names: Vec<String> = listed.split(", ").map(str::to_string).collect();
    names.sort();
    names
}

fn declared_names(table: &fields::TableDoc) -> Vec<String> {
    let mut names: Vec<String> = table.fields.iter().map(|f| f.name.to_string()).collect();
    names.sort();
    names
}

#[test]
fn the_declared_fields_are_the_ones_the_reader_knows() {
    let table = json!({"state": "loop_angle", "advance": TAU, "qqqqqqqqqq": 1});
    let metrics = json!([{"field": "outputs.metrics.a", "variable": "rod_force", "kind": "max",
                          "qqqqqqqqqq": 1}]);
    let refused = resolved(&spec(table, metrics), &mechanism()).unwrap_err();
    let mut cycle = known_by_the_reader(&refused, "cycle.qqqqqqqqqq");
    // `period` is read only to be told its new name.
    cycle.retain(|name| name != "period");
    assert_eq!(cycle, declared_names(&fields::cycle_table()));
    // A metric's `field` is the client's, and a window is read only to be refused.
    let mut metric = known_by_the_reader(&refused, "outputs.metrics.a.qqqqqqqqqq");
    metric.retain(|name| !["field", "from", "to"].contains(&name.as_str()));
    assert_eq!(metric, declared_names(&fields::cycle_metric()));
}

#[test]
fn an_advance_in_degrees_of_an_angle_in_rad_is_told_it_is_in_radians() {
    let d = mechanism();
    for table in [
        json!({"state": "loop_angle", "advance": 360.0}),
        json!({"state": "loop_angle", "period": 360.0}),
    ] {
        let refused = resolved(&spec(table.clone(), json!([])), &d).unwrap_err();
        let (field, rule) = &refused[0];
        assert!(
            rule.contains("360 looks like degrees"),
            "{table}: {refused:?}"
        );
        assert!(rule.contains("6.283185307179586"), "{rule}");
        assert!(
            field == "cycle.advance" || field == "cycle.period",
            "{field}"
        );
    }
    // The same number of a state in another unit, or not a whole number of right angles,
    // is not a mistake.
    assert!(resolved(
        &spec(json!({"state": "loop_angle", "advance": 6.0}), json!([])),
        &d
    )
    .is_ok());
}
