-- Registered robots, shared by every replica. A delete keeps the row as a
-- tombstone (deleted, model NULL) with a new revision, so that a replica that
-- learns of an older change later cannot bring the robot back, and a robot
-- created again under the same name keeps growing revisions.
CREATE SEQUENCE kinserve_robot_revision;

CREATE TABLE kinserve_robots (
    name        text        PRIMARY KEY,
    model       jsonb,
    revision    bigint      NOT NULL,
    deleted     boolean     NOT NULL DEFAULT false,
    created_at  timestamptz NOT NULL DEFAULT now(),
    updated_at  timestamptz NOT NULL DEFAULT now(),
    CONSTRAINT kinserve_robots_model_unless_deleted CHECK (deleted OR model IS NOT NULL)
);
