//! Unit tests of the command line: defaults, ranges, refusals.

use super::*;

#[test]
fn debug_output_hides_the_token_and_the_database_url() {
    let mut c = ServeConfig::for_tests("data".into());
    c.api_token = Some("s3cr3t-value".into());
    c.database_url = Some("postgres://kin:db-pa55word@db.internal:5432/kin".into());
    let shown = format!("{c:?} {:?}", Command::Serve(Box::new(c.clone())));
    assert!(!shown.contains("s3cr3t-value"), "{shown}");
    assert!(!shown.contains("db-pa55word"), "{shown}");
    assert!(!shown.contains("db.internal"), "{shown}");
    assert!(shown.contains("<redacted>"), "{shown}");
}

#[test]
fn durations_parse_with_and_without_units() {
    let ok = |s: &str| parse_duration(s).unwrap();
    assert_eq!(ok("250ms"), Duration::from_millis(250));
    assert_eq!(ok("10s"), Duration::from_secs(10));
    assert_eq!(ok("1.5"), Duration::from_millis(1500));
    assert_eq!(ok("2m"), Duration::from_secs(120));
    assert_eq!(ok("2min"), Duration::from_secs(120));
    assert_eq!(ok("1e3s"), Duration::from_secs(1000));
    assert_eq!(ok("1e3"), Duration::from_secs(1000));
    assert_eq!(ok("24h"), MAX_DURATION);
    assert_eq!(ok("0"), Duration::ZERO);
    for bad in [
        "",
        "s",
        "-1s",
        "abc",
        "inf",
        "NaN",
        "1e",
        "5 parsecs",
        "1ks",
    ] {
        assert!(parse_duration(bad).is_err(), "{bad}");
    }
}

#[test]
fn durations_past_the_maximum_are_refused_not_panicked_on() {
    let huge = format!("{}s", "9".repeat(40));
    for s in [
        "1e30s",
        "24.001h",
        "86401",
        "1e300h",
        "1e308",
        huge.as_str(),
    ] {
        assert_eq!(
            parse_duration(s),
            Err("too long: at most 24h".to_string()),
            "{s}"
        );
    }
    assert_eq!(parse_ik_time_limit("60s"), Ok(MAX_IK_TIME_LIMIT));
    assert_eq!(
        parse_ik_time_limit("61s"),
        Err("too long: at most 60s".to_string())
    );
    assert_eq!(
        parse_ik_time_limit("1e18s"),
        Err("too long: at most 60s".to_string())
    );
}

#[test]
fn counts_and_sizes_past_their_maximum_are_refused() {
    assert_eq!(parse_at_most::<MAX_COUNT>("1000000"), Ok(1_000_000));
    assert_eq!(parse_at_most::<MAX_COUNT>("0"), Ok(0));
    for s in ["1000001", "18446744073709551615", "99999999999999999999999"] {
        assert_eq!(
            parse_at_most::<MAX_COUNT>(s),
            Err("too large: at most 1000000".to_string()),
            "{s}"
        );
    }
    assert!(parse_at_most::<MAX_COUNT>("-1").is_err());
    assert!(parse_at_most::<MAX_COUNT>("ten").is_err());
    assert_eq!(parse_at_most::<MAX_BODY_BYTES>("1073741824"), Ok(1 << 30));
    assert!(parse_at_most::<MAX_BODY_BYTES>("1073741825").is_err());
}

/// Every duration and limit option of `serve` is range-checked: a value
/// past its maximum is a clap error naming the option.
#[test]
fn serve_refuses_out_of_range_options_by_name() {
    let cases = [
        ("--request-timeout", "1e30s", "at most 24h"),
        ("--header-timeout", "25h", "at most 24h"),
        ("--body-timeout", "1e30s", "at most 24h"),
        ("--write-timeout", "1e30s", "at most 24h"),
        ("--linger-timeout", "1e30s", "at most 24h"),
        ("--stream-idle-timeout", "1e30s", "at most 24h"),
        ("--shutdown-grace", "1e30s", "at most 24h"),
        ("--shutdown-timeout", "1e30s", "at most 24h"),
        ("--database-resync-interval", "1e30s", "at most 24h"),
        ("--tls-reload-interval", "1e30s", "at most 24h"),
        ("--ik-time-limit", "1e18s", "at most 60s"),
        ("--max-batch", "1000001", "at most 1000000"),
        ("--max-robots", "1000001", "at most 1000000"),
        ("--max-joints", "4097", "at most 4096"),
        ("--max-links", "4097", "at most 4096"),
        ("--max-body-bytes", "1073741825", "at most 1073741824"),
        ("--max-batch-body-bytes", "1073741825", "at most 1073741824"),
        (
            "--max-concurrent-requests",
            "18446744073709551615",
            "at most 1000000",
        ),
        (
            "--max-connections",
            "18446744073709551615",
            "at most 1000000",
        ),
        ("--max-streams", "1000001", "at most 1000000"),
        ("--max-streams-per-connection", "1000001", "at most 1000000"),
        (
            "--max-buffered-request-bytes",
            "18446744073709551615",
            "at most 68719476736",
        ),
        (
            "--max-buffered-response-bytes",
            "18446744073709551615",
            "at most 68719476736",
        ),
        ("--max-concurrent-batches", "1000001", "at most 1000000"),
        ("--grpc-stream-window", "16777217", "from 65535 to 16777216"),
        ("--grpc-stream-window", "65534", "from 65535 to 16777216"),
    ];
    for (flag, value, why) in cases {
        let err = ServeOnly::try_parse_from(["kinserve", flag, value])
            .map(|_| ())
            .expect_err(flag)
            .to_string();
        assert!(
            err.contains(&format!("invalid value '{value}' for '{flag} ")),
            "{err}"
        );
        assert!(err.contains(why), "{err}");
    }
}

#[test]
fn the_grpc_stream_window_takes_bytes_within_http2s_range() {
    let parse = |v: &str| {
        ServeOnly::try_parse_from(["kinserve", "--grpc-stream-window", v])
            .map(|s| s.c.grpc_stream_window)
            .ok()
    };
    assert_eq!(parse("65535"), Some(65_535));
    assert_eq!(parse("16777216"), Some(16 << 20));
    assert_eq!(parse("1048576"), Some(1 << 20));
    assert_eq!(
        ServeConfig::flag_defaults().grpc_stream_window,
        crate::api::grpc::DEFAULT_STREAM_WINDOW
    );
}

#[test]
fn test_configuration_is_the_flag_defaults_but_for_listeners_data_grace_and_writes() {
    let t = ServeConfig::for_tests("somewhere".into());
    let d = ServeConfig::flag_defaults();
    assert_eq!(t.http_addr, "127.0.0.1:0".parse().unwrap());
    assert_eq!(t.grpc_addr, t.http_addr);
    assert_eq!(t.data_dir, PathBuf::from("somewhere"));
    assert_eq!(t.shutdown_grace, Duration::ZERO);
    assert_eq!(d.shutdown_grace, Duration::from_secs(5));
    assert!(t.allow_unauthenticated_writes);
    assert!(
        !d.allow_unauthenticated_writes,
        "read-only without a token by default"
    );
    let same = |c: &ServeConfig| {
        let c = ServeConfig {
            http_addr: d.http_addr,
            grpc_addr: d.grpc_addr,
            data_dir: d.data_dir.clone(),
            shutdown_grace: d.shutdown_grace,
            allow_unauthenticated_writes: d.allow_unauthenticated_writes,
            ..c.clone()
        };
        format!("{c:?}")
    };
    assert_eq!(same(&t), format!("{d:?}"));
    // The flag defaults are the service's and the model's defaults.
    assert_eq!(d.service_limits(), ServiceLimits::default());
}
