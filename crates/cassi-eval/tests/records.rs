//! The typed records: each round-trips with its header; files written before
//! the header (fixtures/v0, made by cassi at 74c3e19) read as version 0; and
//! every file the reader refuses is named with what is wrong with it.

use std::path::{Path, PathBuf};

use cassi_core::calib::Calibration;
use cassi_eval::records::{
    Record, SceneRecord, SimulationRecord, SummaryRecord, read_record, read_versioned, to_json,
    write_record,
};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/v0")
        .join(name)
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir()
        .join(format!("cassi-records-{}", std::process::id()))
        .join(name);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// Reads a v0 fixture as `R`, writes it, reads it back as version 1: the
/// written file is the old object plus the header, field for field where
/// `exact` (the old summary.json went through `json!`, which wrote f32
/// settings widened to f64, e.g. 0.07000000029802322; the typed writer
/// writes the same f32 as 0.07).
fn round_trip<R: Record>(fixture_name: &str, exact: bool) -> R {
    let old = read_versioned::<R>(fixture(fixture_name)).unwrap();
    assert_eq!(old.version, 0, "{fixture_name}: headerless means version 0");
    let path = scratch("round-trip").join(fixture_name);
    write_record(&path, &old.record).unwrap();
    let back = read_versioned::<R>(&path).unwrap();
    assert_eq!(back.version, R::VERSION);

    let mut written = json(&path);
    let object = written.as_object_mut().unwrap();
    assert_eq!(object.remove("format").unwrap(), R::FORMAT);
    assert_eq!(object.remove("version").unwrap(), R::VERSION);
    let fixture_json = json(&fixture(fixture_name));
    if exact {
        assert_eq!(written, fixture_json, "{fixture_name}");
    } else {
        let keys =
            |v: &serde_json::Value| v.as_object().unwrap().keys().cloned().collect::<Vec<_>>();
        assert_eq!(keys(&written), keys(&fixture_json), "{fixture_name}");
    }
    // and the record read back writes the same text again
    assert_eq!(
        to_json(&back.record).unwrap(),
        to_json(&old.record).unwrap()
    );
    back.record
}

#[test]
fn each_record_round_trips_and_old_files_read_as_version_0() {
    let cal: Calibration = round_trip("calibration.json", true);
    assert_eq!(cal.preset, "default");
    assert_eq!(cal.parameters.dx, 1.5000525971892626);
    let sidecar: SimulationRecord = round_trip("sidecar.json", true);
    assert_eq!(sidecar.instrument.bands, 4);
    assert!(sidecar.physical.is_none());
    let physical: SimulationRecord = round_trip("sidecar_physical.json", true);
    assert_eq!(physical.physical.unwrap().oversample, 2);
    let scene: SceneRecord = round_trip("scene.json", true);
    assert_eq!(scene.result.scene, "synthetic_0");
    assert!(scene.inputs.is_some());
    let summary: SummaryRecord = round_trip("summary.json", false);
    assert_eq!(summary.summary.scenes, vec!["synthetic_0".to_string()]);
}

/// The message of reading `text` (in a file named `name`) as `R`.
fn refusal<R: Record + std::fmt::Debug>(name: &str, text: &str) -> String {
    let path = scratch("refused").join(name);
    std::fs::write(&path, text).unwrap();
    read_record::<R>(&path).unwrap_err().to_string()
}

fn assert_says(message: &str, needles: &[&str]) {
    for n in needles {
        assert!(message.contains(n), "{message:?} should say {n:?}");
    }
}

fn headed(fixture_name: &str, format: &str, version: &str) -> String {
    let mut v = json(&fixture(fixture_name));
    let text = serde_json::to_string(&v).unwrap();
    // the header first, as the writer puts it
    v = serde_json::from_str(&format!(
        "{{\"format\": {format}, \"version\": {version}, {}",
        &text[1..]
    ))
    .unwrap();
    serde_json::to_string_pretty(&v).unwrap()
}

#[test]
fn refusals_name_the_file_and_the_problem() {
    assert_says(
        &refusal::<Calibration>("truncated.json", "{\"preset\": "),
        &["truncated.json", "not valid JSON"],
    );
    assert_says(
        &refusal::<Calibration>("list.json", "[1, 2]"),
        &["list.json", "an array", "not a JSON object"],
    );
    // another kind of record, with a header or as an old file
    let sidecar = std::fs::read_to_string(fixture("sidecar.json")).unwrap();
    assert_says(
        &refusal::<Calibration>("old_sidecar.json", &sidecar),
        &["old_sidecar.json is a cassi-simulation record, not a cassi-calibration file"],
    );
    assert_says(
        &refusal::<SimulationRecord>(
            "cal.json",
            &headed("calibration.json", "\"cassi-calibration\"", "1"),
        ),
        &["cal.json is a cassi-calibration record, not a cassi-simulation file"],
    );
    assert_says(
        &refusal::<SceneRecord>(
            "foreign.json",
            "{\"format\": \"acme-cube\", \"version\": 1}",
        ),
        &["foreign.json is a acme-cube record, not a cassi-study-scene file"],
    );
    // a newer version than this build reads
    assert_says(
        &refusal::<Calibration>(
            "future.json",
            &headed("calibration.json", "\"cassi-calibration\"", "2"),
        ),
        &[
            "future.json",
            "version 2",
            "newer cassi",
            "reads versions up to 1",
        ],
    );
    assert_says(
        &refusal::<SummaryRecord>(
            "bad_version.json",
            &headed("summary.json", "\"cassi-study-summary\"", "\"one\""),
        ),
        &["bad_version.json", "\"version\" must be a whole number"],
    );
    assert_says(
        &refusal::<SceneRecord>("format_number.json", "{\"format\": 1, \"version\": 1}"),
        &[
            "format_number.json",
            "\"format\" must be a string, got a number",
        ],
    );
    assert_says(
        &refusal::<SummaryRecord>(
            "no_version.json",
            "{\"format\": \"cassi-study-summary\", \"study\": {}}",
        ),
        &["no_version.json", "\"version\" is missing"],
    );
    // the right kind with a field missing or wrong: serde's words
    let mut cal = json(&fixture("calibration.json"));
    cal.as_object_mut().unwrap().remove("score");
    assert_says(
        &refusal::<Calibration>("no_score.json", &cal.to_string()),
        &[
            "no_score.json",
            "invalid cassi-calibration file (version 0)",
            "missing field `score`",
        ],
    );
    let wrong = headed("sidecar.json", "\"cassi-simulation\"", "1")
        .replace("\"bands\": 4", "\"bands\": \"four\"");
    assert_says(
        &refusal::<SimulationRecord>("wrong.json", &wrong),
        &["wrong.json", "(version 1)", "invalid type: string \"four\""],
    );
    // neither a header nor the old shape
    assert_says(
        &refusal::<SceneRecord>("other.json", "{\"hello\": 1}"),
        &[
            "other.json",
            "not a cassi-study-scene file",
            "no \"format\" header",
            "missing field",
        ],
    );
    let missing = fixture("absent.json");
    let e = read_record::<Calibration>(&missing).unwrap_err();
    assert!(e.is_missing());
    assert_says(&e.to_string(), &["absent.json", "cannot read"]);
}
