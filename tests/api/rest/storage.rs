//! REST persistence: robots surviving a restart, corrupt or unreadable files
//! at start-up, and failed writes.

use serde_json::{Value, json};

use crate::helpers::pose::assert_pose_eq;
use crate::helpers::*;

// ---------------------------------------------------------------- persistence

#[tokio::test]
async fn registered_robots_survive_a_restart() {
    let tmp = tempfile::tempdir().unwrap();
    let app = spawn_in(tmp.path(), |_| {}).await;
    assert_eq!(
        app.post("/v1/robots", &planar_model("kept")).await.status(),
        201
    );
    assert_eq!(
        app.post("/v1/robots", &planar_model("replaced"))
            .await
            .status(),
        201
    );
    assert_eq!(
        app.post("/v1/robots", &planar_model("deleted"))
            .await
            .status(),
        201
    );
    let mut replacement = planar_model("replaced");
    replacement["links"][1]["a"] = json!(0.25);
    replacement["description"] = json!("second version");
    let r = app
        .client
        .put(format!("{}/v1/robots/replaced", app.http))
        .json(&replacement)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    let r = app
        .client
        .delete(format!("{}/v1/robots/deleted", app.http))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 204);
    // Written before the answer: the files are there already.
    let dir = tmp.path().join("robots");
    assert!(dir.join("kept.json").is_file());
    assert!(dir.join("replaced.json").is_file());
    assert!(!dir.join("deleted.json").exists());
    let on_disk: Value =
        serde_json::from_slice(&std::fs::read(dir.join("replaced.json")).unwrap()).unwrap();
    assert!(json_eq(&on_disk, &replacement), "{on_disk}");
    // Atomic writes leave no temporary files behind.
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, ["kept.json", "replaced.json"]);
    let before = fk_ok(&app, "replaced", json!({"joints": [0.3, -0.2]})).await;
    app.stop().await.unwrap();

    let app = spawn_in(tmp.path(), |_| {}).await;
    let got: Value = app.get("/v1/robots/kept").await.json().await.unwrap();
    assert!(json_eq(&got, &planar_model("kept")), "{got}");
    let got: Value = app.get("/v1/robots/replaced").await.json().await.unwrap();
    assert!(json_eq(&got, &replacement), "{got}");
    problem(app.get("/v1/robots/deleted").await, 404).await;
    let list: Value = app.get("/v1/robots").await.json().await.unwrap();
    let kept = list["robots"]
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r["name"] == "kept")
        .unwrap();
    assert_eq!(kept["source"], "registered");
    let after = fk_ok(&app, "replaced", json!({"joints": [0.3, -0.2]})).await;
    assert_pose_eq(
        &after["pose"],
        &before["pose"],
        SAME_LIB_TOL,
        "same model after restart",
    );
    // Still registered, not built in: it can be deleted, and stays deleted.
    let r = app
        .client
        .delete(format!("{}/v1/robots/kept", app.http))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 204);
    app.stop().await.unwrap();
    let app = spawn_in(tmp.path(), |_| {}).await;
    assert_eq!(app.get("/v1/robots/kept").await.status(), 404);
    assert_eq!(app.get("/v1/robots/replaced").await.status(), 200);
}

#[tokio::test]
async fn corrupt_or_unreadable_files_are_skipped_at_start_up_and_left_in_place() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("robots");
    std::fs::create_dir_all(&dir).unwrap();
    let good = serde_json::to_vec_pretty(&planar_model("good")).unwrap();
    std::fs::write(dir.join("good.json"), &good).unwrap();
    let corrupt = b"{\"name\": \"corrupt\", \"convention\": ".to_vec();
    std::fs::write(dir.join("corrupt.json"), &corrupt).unwrap();
    let mut bad = planar_model("invalid");
    bad["links"] = json!([]);
    let invalid = serde_json::to_vec(&bad).unwrap();
    std::fs::write(dir.join("invalid.json"), &invalid).unwrap();
    let mismatch = serde_json::to_vec(&planar_model("someone_else")).unwrap();
    std::fs::write(dir.join("mismatch.json"), &mismatch).unwrap();
    let clash = serde_json::to_vec(&planar_model("puma560")).unwrap();
    std::fs::write(dir.join("puma560.json"), &clash).unwrap();
    // Unreadable (a directory where a file should be; works even as root).
    std::fs::create_dir(dir.join("unreadable.json")).unwrap();

    let app = spawn_in(tmp.path(), |_| {}).await;
    assert_eq!(app.get("/readyz").await.status(), 200);
    assert_eq!(app.get("/v1/robots/good").await.status(), 200);
    for name in [
        "corrupt",
        "invalid",
        "mismatch",
        "someone_else",
        "unreadable",
    ] {
        problem(app.get(&format!("/v1/robots/{name}")).await, 404).await;
    }
    // The built-in wins over a stored file of the same name.
    let got: Value = app.get("/v1/robots/puma560").await.json().await.unwrap();
    assert!(json_eq(&got, &builtin_file("puma560")));
    let list: Value = app.get("/v1/robots").await.json().await.unwrap();
    let registered: Vec<&str> = list["robots"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|r| r["source"] == "registered")
        .map(|r| r["name"].as_str().unwrap())
        .collect();
    assert_eq!(registered, ["good"]);
    // The server works normally beside them.
    assert_eq!(
        app.post("/v1/robots", &planar_model("fresh"))
            .await
            .status(),
        201
    );
    app.stop().await.unwrap();

    // Left in place, untouched.
    assert_eq!(std::fs::read(dir.join("corrupt.json")).unwrap(), corrupt);
    assert_eq!(std::fs::read(dir.join("invalid.json")).unwrap(), invalid);
    assert_eq!(std::fs::read(dir.join("mismatch.json")).unwrap(), mismatch);
    assert_eq!(std::fs::read(dir.join("puma560.json")).unwrap(), clash);
    assert!(dir.join("unreadable.json").is_dir());
    assert_eq!(std::fs::read(dir.join("good.json")).unwrap(), good);
}

/// When the store cannot write, the API answers 507 and changes nothing.
#[tokio::test]
async fn a_failed_write_is_507_and_changes_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let app = spawn_in(tmp.path(), |_| {}).await;
    assert_eq!(
        app.post("/v1/robots", &planar_model("before"))
            .await
            .status(),
        201
    );
    // Replace the robots directory by a plain file: every write fails (even as root).
    let dir = tmp.path().join("robots");
    std::fs::remove_dir_all(&dir).unwrap();
    std::fs::write(&dir, b"not a directory").unwrap();
    let p = problem(app.post("/v1/robots", &planar_model("after")).await, 507).await;
    assert_eq!(p["type"], "urn:kinserve:problem:storage");
    problem(app.get("/v1/robots/after").await, 404).await;
    let mut replacement = planar_model("before");
    replacement["links"][0]["a"] = json!(0.9);
    let r = app
        .client
        .put(format!("{}/v1/robots/before", app.http))
        .json(&replacement)
        .send()
        .await
        .unwrap();
    problem(r, 507).await;
    let got: Value = app.get("/v1/robots/before").await.json().await.unwrap();
    assert!(json_eq(&got, &planar_model("before")), "unchanged: {got}");
}

// ---------------------------------------------------------------- the data directory

/// Only regular files of bounded size are read at start-up: a FIFO (which
/// would block the read forever), a 3 GB sparse file (which would be read
/// whole) and a directory are skipped and left in place; only the server's
/// own temporary files are cleaned, nothing else that looks like one.
#[tokio::test]
async fn special_oversized_and_foreign_files_in_the_data_dir_are_left_alone() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("robots");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(
        dir.join("good.json"),
        serde_json::to_vec(&planar_model("good")).unwrap(),
    )
    .unwrap();
    let fifo = dir.join("fifo.json");
    let made = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap();
    assert!(made.success());
    let huge = dir.join("huge.json");
    std::fs::File::create(&huge)
        .unwrap()
        .set_len(3 << 30)
        .unwrap();
    let own_tmp = dir.join(".good.json.tmp-0123456789abcdef0123456789abcdef");
    std::fs::write(&own_tmp, b"{").unwrap();
    let foreign = [
        ".my.tmp.notes",
        ".good.json.tmp-mine",
        ".Bad.json.tmp-0123456789abcdef0123456789abcdef",
    ];
    for f in foreign {
        std::fs::write(dir.join(f), b"keep me").unwrap();
    }

    let app = tokio::time::timeout(
        std::time::Duration::from_secs(60),
        spawn_in(tmp.path(), |_| {}),
    )
    .await
    .expect("start-up does not hang on a FIFO");
    assert_eq!(app.get("/v1/robots/good").await.status(), 200);
    for name in ["fifo", "huge"] {
        problem(app.get(&format!("/v1/robots/{name}")).await, 404).await;
    }
    app.stop().await.unwrap();
    assert!(fifo.exists() && huge.exists(), "skipped files stay");
    assert!(
        !own_tmp.exists(),
        "the server's own temporary file is cleaned"
    );
    for f in foreign {
        assert_eq!(std::fs::read(dir.join(f)).unwrap(), b"keep me", "{f}");
    }

    // The reasons, as the start-up log gives them.
    let err = kinserve::model::read_robot_file(&fifo).unwrap_err();
    assert!(err.to_string().contains("FIFO"), "{err}");
    let err = kinserve::model::read_robot_file(&huge).unwrap_err();
    assert!(err.to_string().contains("16 MiB"), "{err}");
    let err = kinserve::model::read_robot_file(&dir).unwrap_err();
    assert!(err.to_string().contains("directory"), "{err}");
}

/// `robots` in the data directory that is a plain file or a dangling link
/// stops start-up with an error naming it and saying what is wrong.
#[tokio::test]
async fn a_robots_path_that_is_not_a_directory_stops_start_up_naming_it() {
    for (kind, make) in [
        (
            "not a directory",
            &(|p: &std::path::Path| std::fs::write(p, b"x").unwrap()) as &dyn Fn(&std::path::Path),
        ),
        ("dangling symbolic link", &|p: &std::path::Path| {
            std::os::unix::fs::symlink(p.with_file_name("nowhere"), p).unwrap()
        }),
    ] {
        let tmp = tempfile::tempdir().unwrap();
        let robots = tmp.path().join("robots");
        make(&robots);
        let config = kinserve::config::ServeConfig::for_tests(tmp.path().to_path_buf());
        let Err(err) = kinserve::App::build(config).await else {
            panic!("start-up must fail when robots/ is a {kind}");
        };
        let msg = err.to_string();
        assert!(msg.contains(kind), "{msg}");
        assert!(msg.contains(&robots.display().to_string()), "{msg}");
    }
}
