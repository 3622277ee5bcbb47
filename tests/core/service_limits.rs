//! Limits set in code (not through the command line, which caps them) never
//! make the service's deadline arithmetic panic.

use std::time::Duration;

use kinserve::model::IkSpec;
use kinserve::registry::{MemoryStore, Registry};
use kinserve::service::{Service, ServiceLimits, WriteAccess};

fn service(ik_time_limit: Duration, ik_batch_time_limit: Duration) -> Service {
    let limits = ServiceLimits {
        ik_time_limit,
        ik_batch_time_limit,
        ..ServiceLimits::default()
    };
    let registry = Registry::new(Box::new(MemoryStore));
    registry.load_builtins(None, &limits.model);
    Service::new(registry, limits, WriteAccess::Open)
}

fn spec(v: serde_json::Value) -> IkSpec {
    serde_json::from_value(v).unwrap()
}

#[test]
fn ik_with_the_longest_representable_limits_answers_instead_of_panicking() {
    let s = service(Duration::MAX, Duration::MAX);
    let entry = s.robot("planar_2dof").unwrap();
    // Reachable (x² + y² = 0.25 ≤ 0.7²): converges long before any deadline.
    let one =
        spec(serde_json::json!({"target": {"position": [0.3, 0.4, 0.0]}, "position_only": true}));
    let answer = s.ik(&entry.robot, &one).unwrap();
    assert!(answer.converged);
    let batch = serde_json::from_value(serde_json::json!({
        "targets": [{"position": [0.3, 0.4, 0.0]}, {"position": [0.5, 0.0, 0.0]}],
        "position_only": true,
    }))
    .unwrap();
    let answers = s.ik_batch(&entry.robot, &batch).unwrap();
    assert_eq!(answers.len(), 2);
    assert!(answers.iter().all(|a| a.converged));
}
