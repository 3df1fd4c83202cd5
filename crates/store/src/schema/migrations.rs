//! Every migration of the schema, in order, as SQLite and PostgreSQL spell
//! it: the data the migrating code in the parent module applies.

/// One schema migration, as SQLite and PostgreSQL spell it.
#[derive(Debug, Clone, Copy)]
pub struct Migration {
    /// What it adds.
    pub what: &'static str,
    /// SQLite's text.
    pub sqlite: &'static str,
    /// PostgreSQL's text.
    pub postgres: &'static str,
}

/// Schema migrations, in order; never edit one that has shipped, add a new one.
pub const MIGRATIONS: &[Migration] = &[
    Migration {
        what: "runs, points, per-instrument results, the event log",
        sqlite: MIGRATION_1_SQLITE,
        postgres: "CREATE TABLE runs (
        id TEXT PRIMARY KEY,
        station TEXT NOT NULL,
        plan_json TEXT NOT NULL,
        software_version TEXT NOT NULL,
        state TEXT NOT NULL,
        reason TEXT,
        started_at BIGINT NOT NULL,
        finished_at BIGINT,
        starts BIGINT NOT NULL DEFAULT 1
    );
    CREATE TABLE points (
        run_id TEXT NOT NULL REFERENCES runs(id),
        step BIGINT NOT NULL,
        slot BIGINT NOT NULL,
        serial TEXT NOT NULL,
        mount TEXT NOT NULL,
        g_nominal DOUBLE PRECISION NOT NULL,
        direction TEXT NOT NULL,
        g_applied DOUBLE PRECISION NOT NULL,
        rate_deg_s DOUBLE PRECISION NOT NULL,
        output_hz DOUBLE PRECISION NOT NULL,
        std_hz DOUBLE PRECISION NOT NULL,
        n BIGINT NOT NULL,
        t0_s DOUBLE PRECISION NOT NULL,
        t1_s DOUBLE PRECISION NOT NULL,
        PRIMARY KEY (run_id, step, slot)
    );
    CREATE TABLE results (
        run_id TEXT NOT NULL REFERENCES runs(id),
        slot BIGINT NOT NULL,
        serial TEXT NOT NULL,
        outcome TEXT NOT NULL,
        k2_max_ug_per_g2 DOUBLE PRECISION,
        record_json TEXT NOT NULL,
        PRIMARY KEY (run_id, slot)
    );
    CREATE INDEX results_serial ON results(serial);
    CREATE TABLE events (
        seq BIGSERIAL PRIMARY KEY,
        run_id TEXT NOT NULL,
        at BIGINT NOT NULL,
        kind TEXT NOT NULL,
        json TEXT NOT NULL
    );",
    },
    Migration {
        what: "the one-second values of every instrument (and the rate), as the engine saw them",
        sqlite: MIGRATION_2_SQLITE,
        postgres: "CREATE TABLE values_1s (
        run_id TEXT NOT NULL,
        t_s DOUBLE PRECISION NOT NULL,
        slot BIGINT NOT NULL,
        output_hz DOUBLE PRECISION,
        rate_deg_s DOUBLE PRECISION NOT NULL,
        on_speed BIGINT NOT NULL,
        PRIMARY KEY (run_id, t_s, slot)
    );",
    },
    Migration {
        what: "stations, the station config and device identities of a run, units (radius per mounting), operator actions",
        sqlite: "CREATE TABLE stations (
        name TEXT PRIMARY KEY,
        first_seen INTEGER NOT NULL,
        last_seen INTEGER NOT NULL
    );
    ALTER TABLE runs ADD COLUMN station_config TEXT;
    ALTER TABLE runs ADD COLUMN devices_json TEXT;
    CREATE TABLE units (
        run_id TEXT NOT NULL REFERENCES runs(id),
        slot INTEGER NOT NULL,
        mount TEXT NOT NULL,
        serial TEXT NOT NULL,
        drawing_radius_m REAL NOT NULL,
        radius_m REAL NOT NULL,
        PRIMARY KEY (run_id, slot, mount)
    );
    CREATE TABLE operator_actions (
        seq INTEGER PRIMARY KEY AUTOINCREMENT,
        run_id TEXT NOT NULL,
        at INTEGER NOT NULL,
        who TEXT NOT NULL,
        action TEXT NOT NULL
    );",
        postgres: "CREATE TABLE stations (
        name TEXT PRIMARY KEY,
        first_seen BIGINT NOT NULL,
        last_seen BIGINT NOT NULL
    );
    ALTER TABLE runs ADD COLUMN station_config TEXT;
    ALTER TABLE runs ADD COLUMN devices_json TEXT;
    CREATE TABLE units (
        run_id TEXT NOT NULL REFERENCES runs(id),
        slot BIGINT NOT NULL,
        mount TEXT NOT NULL,
        serial TEXT NOT NULL,
        drawing_radius_m DOUBLE PRECISION NOT NULL,
        radius_m DOUBLE PRECISION NOT NULL,
        PRIMARY KEY (run_id, slot, mount)
    );
    CREATE TABLE operator_actions (
        seq BIGSERIAL PRIMARY KEY,
        run_id TEXT NOT NULL,
        at BIGINT NOT NULL,
        who TEXT NOT NULL,
        action TEXT NOT NULL
    );",
    },
    Migration {
        what: "users of the web UI (role, password hash) and the audit log of their actions",
        sqlite: "CREATE TABLE users (
        name TEXT PRIMARY KEY,
        role TEXT NOT NULL,
        password_hash TEXT NOT NULL,
        created_at INTEGER NOT NULL
    );
    CREATE TABLE audit (
        seq INTEGER PRIMARY KEY AUTOINCREMENT,
        at INTEGER NOT NULL,
        who TEXT NOT NULL,
        action TEXT NOT NULL,
        detail TEXT NOT NULL
    );",
        postgres: "CREATE TABLE users (
        name TEXT PRIMARY KEY,
        role TEXT NOT NULL,
        password_hash TEXT NOT NULL,
        created_at BIGINT NOT NULL
    );
    CREATE TABLE audit (
        seq BIGSERIAL PRIMARY KEY,
        at BIGINT NOT NULL,
        who TEXT NOT NULL,
        action TEXT NOT NULL,
        detail TEXT NOT NULL
    );",
    },
    Migration {
        what: "the instruments' temperatures: each one-second value's, each point's mean and change",
        sqlite: "ALTER TABLE values_1s ADD COLUMN temperature_c REAL;
    ALTER TABLE points ADD COLUMN temperature_c REAL;
    ALTER TABLE points ADD COLUMN temperature_change_c REAL;",
        postgres: "ALTER TABLE values_1s ADD COLUMN temperature_c DOUBLE PRECISION;
    ALTER TABLE points ADD COLUMN temperature_c DOUBLE PRECISION;
    ALTER TABLE points ADD COLUMN temperature_change_c DOUBLE PRECISION;",
    },
    Migration {
        what: "a retest's link to the run it retests",
        sqlite: "ALTER TABLE runs ADD COLUMN retest_of TEXT;
    CREATE INDEX runs_retest_of ON runs (retest_of);",
        postgres: "ALTER TABLE runs ADD COLUMN retest_of TEXT;
    CREATE INDEX runs_retest_of ON runs (retest_of);",
    },
    Migration {
        what: "the equipment register: each device's calibration certificate and due date",
        sqlite: "CREATE TABLE equipment (
        role TEXT PRIMARY KEY,
        identity TEXT NOT NULL,
        certificate TEXT NOT NULL,
        calibrated_on TEXT NOT NULL,
        due_on TEXT NOT NULL,
        updated_by TEXT NOT NULL,
        updated_at INTEGER NOT NULL
    );",
        postgres: "CREATE TABLE equipment (
        role TEXT PRIMARY KEY,
        identity TEXT NOT NULL,
        certificate TEXT NOT NULL,
        calibrated_on TEXT NOT NULL,
        due_on TEXT NOT NULL,
        updated_by TEXT NOT NULL,
        updated_at BIGINT NOT NULL
    );",
    },
    Migration {
        what: "each user's language for the web UI and the reports they download",
        sqlite: "ALTER TABLE users ADD COLUMN language TEXT;",
        postgres: "ALTER TABLE users ADD COLUMN language TEXT;",
    },
    Migration {
        what: "web sessions kept across restarts (hashed tokens)",
        sqlite: "CREATE TABLE sessions (
        token_hash TEXT PRIMARY KEY,
        user_name TEXT NOT NULL,
        csrf TEXT NOT NULL,
        last_seen INTEGER NOT NULL
    );",
        postgres: "CREATE TABLE sessions (
        token_hash TEXT PRIMARY KEY,
        user_name TEXT NOT NULL,
        csrf TEXT NOT NULL,
        last_seen BIGINT NOT NULL
    );",
    },
    Migration {
        what: "why a run ended, as a key and values (JSON), for reports in another language",
        sqlite: "ALTER TABLE runs ADD COLUMN reason_wording TEXT;",
        postgres: "ALTER TABLE runs ADD COLUMN reason_wording TEXT;",
    },
    Migration {
        what: "the fleet: each station's heartbeat (state, run, progress, address)",
        sqlite: "ALTER TABLE stations ADD COLUMN state TEXT;
    ALTER TABLE stations ADD COLUMN run_id TEXT;
    ALTER TABLE stations ADD COLUMN steps_done INTEGER;
    ALTER TABLE stations ADD COLUMN steps_total INTEGER;
    ALTER TABLE stations ADD COLUMN address TEXT;
    CREATE INDEX runs_station ON runs (station, started_at);",
        postgres: "ALTER TABLE stations ADD COLUMN state TEXT;
    ALTER TABLE stations ADD COLUMN run_id TEXT;
    ALTER TABLE stations ADD COLUMN steps_done BIGINT;
    ALTER TABLE stations ADD COLUMN steps_total BIGINT;
    ALTER TABLE stations ADD COLUMN address TEXT;
    CREATE INDEX runs_station ON runs (station, started_at);",
    },
    Migration {
        what: "each run's sequence number on its station that day, for its readable label",
        sqlite: MIGRATION_RUN_SEQ,
        postgres: MIGRATION_RUN_SEQ_PG,
    },
    Migration {
        what: "indexes on a run's events and operator actions; checks on every enumeration (PostgreSQL); the migration history",
        sqlite: "CREATE INDEX events_run ON events (run_id, seq);
    CREATE INDEX operator_actions_run ON operator_actions (run_id, seq);
    CREATE TABLE spinbench_migrations (
        version INTEGER PRIMARY KEY,
        what TEXT NOT NULL,
        applied_at INTEGER,
        release TEXT
    );",
        // NOT VALID: rows already stored are not re-checked (an archive is
        // never refused at an upgrade); every new row is.
        postgres: "CREATE INDEX events_run ON events (run_id, seq);
    CREATE INDEX operator_actions_run ON operator_actions (run_id, seq);
    ALTER TABLE runs ADD CONSTRAINT runs_state_known CHECK (state IN
        ('idle', 'running', 'prompting', 'paused', 'stopping', 'completed', 'faulted', 'aborted', 'interrupted')) NOT VALID;
    ALTER TABLE results ADD CONSTRAINT results_outcome_known CHECK (outcome IN
        ('pass', 'marginal', 'fail', 'incomplete', 'inconclusive')) NOT VALID;
    ALTER TABLE points ADD CONSTRAINT points_mount_known CHECK (mount IN ('P', 'N')) NOT VALID;
    ALTER TABLE points ADD CONSTRAINT points_direction_known CHECK (direction IN ('up', 'down')) NOT VALID;
    ALTER TABLE users ADD CONSTRAINT users_role_known CHECK (role IN ('operator', 'engineer', 'admin')) NOT VALID;
    CREATE TABLE spinbench_migrations (
        version BIGINT PRIMARY KEY,
        what TEXT NOT NULL,
        applied_at TIMESTAMPTZ,
        release TEXT
    );",
    },
    Migration {
        what: "the record's layout version; the result's figures as columns (k2 and U95 per mounting, K2 and U95, measurand, limit), filled from the stored records; foreign keys from a run's rows to the run, from a run to its station and from a session to its user (PostgreSQL)",
        sqlite: MIGRATION_14_SQLITE,
        postgres: MIGRATION_14_POSTGRES,
    },
    Migration {
        what: "PostgreSQL's own types: times as timestamptz, calibration dates as date, on-speed as boolean, plans, device lists, records and events as jsonb (SQLite keeps its types)",
        // SQLite has no such types: nothing changes there.
        sqlite: "SELECT 1;",
        postgres: MIGRATION_15_POSTGRES,
    },
    Migration {
        what: "slots numbered as people number them (1, 2, …, as on the fixtures, the API, the reports and /metrics) in points, results, units and values_1s",
        sqlite: MIGRATION_16,
        postgres: MIGRATION_16,
    },
    Migration {
        what: "the equipment register kept per station (station, role); a station's identity, kind (server or command line) and retirement in the fleet; a result's revision (each engineer's change after the run counts one)",
        sqlite: MIGRATION_17_SQLITE,
        postgres: MIGRATION_17_POSTGRES,
    },
    Migration {
        what: "an operator action's wording (its prompt as fixture codes, so a report words it in any language) and the run's notices and faults kept with its record (run_notices: they stay when `prune` removes the event log)",
        sqlite: "ALTER TABLE operator_actions ADD COLUMN wording_json TEXT;
    CREATE TABLE run_notices (
        seq INTEGER PRIMARY KEY AUTOINCREMENT,
        run_id TEXT NOT NULL REFERENCES runs(id),
        at INTEGER NOT NULL,
        kind TEXT NOT NULL CHECK (kind IN ('notice', 'fault')),
        message TEXT NOT NULL,
        wording_json TEXT
    );
    CREATE INDEX run_notices_run ON run_notices (run_id, seq);",
        postgres: "ALTER TABLE operator_actions ADD COLUMN wording_json jsonb;
    CREATE TABLE run_notices (
        seq BIGSERIAL PRIMARY KEY,
        run_id TEXT NOT NULL REFERENCES runs(id),
        at timestamptz NOT NULL,
        kind TEXT NOT NULL CHECK (kind IN ('notice', 'fault')),
        message TEXT NOT NULL,
        wording_json jsonb
    );
    CREATE INDEX run_notices_run ON run_notices (run_id, seq);",
    },
    Migration {
        what: "indexes for history that does not read everything: the runs newest first (the paged run list), an instrument's units by serial",
        sqlite: "CREATE INDEX runs_started ON runs (started_at, id);
    CREATE INDEX units_serial ON units (serial);",
        postgres: "CREATE INDEX runs_started ON runs (started_at, id);
    CREATE INDEX units_serial ON units (serial);",
    },
    Migration {
        what: "each run's station time zone (its offset from UTC when it started), for its label's day",
        sqlite: "ALTER TABLE runs ADD COLUMN utc_offset_s INTEGER NOT NULL DEFAULT 0
        CHECK (utc_offset_s BETWEEN -43200 AND 50400);",
        postgres: "ALTER TABLE runs ADD COLUMN utc_offset_s integer NOT NULL DEFAULT 0
        CONSTRAINT runs_utc_offset_s_range CHECK (utc_offset_s BETWEEN -43200 AND 50400);",
    },
    Migration {
        what: "the analyst's view (analyst_results: one row per instrument and run, what its verdict judged, the rule, the reasons' codes, the plan and the operator as columns) and, on PostgreSQL, a comment on every table and on the view",
        sqlite: MIGRATION_21_SQLITE,
        postgres: MIGRATION_21_POSTGRES,
    },
    Migration {
        what: "API tokens for machine clients (a name, a role, the SHA-256 of the secret, who made and revoked it)",
        sqlite: "CREATE TABLE api_tokens (
        name TEXT PRIMARY KEY,
        role TEXT NOT NULL CHECK (role IN ('operator', 'engineer', 'admin')),
        secret_hash TEXT NOT NULL UNIQUE,
        created_by TEXT NOT NULL,
        created_at INTEGER NOT NULL,
        last_used_at INTEGER,
        revoked_at INTEGER,
        revoked_by TEXT
    );",
        postgres: "CREATE TABLE api_tokens (
        name TEXT PRIMARY KEY,
        role TEXT NOT NULL CONSTRAINT api_tokens_role_known CHECK (role IN ('operator', 'engineer', 'admin')),
        secret_hash TEXT NOT NULL UNIQUE,
        created_by TEXT NOT NULL,
        created_at timestamptz NOT NULL,
        last_used_at timestamptz,
        revoked_at timestamptz,
        revoked_by TEXT
    );
    COMMENT ON TABLE api_tokens IS 'API tokens of machine clients (hashed secrets): no analyst reads it.';",
    },
];

/// The analyst's view (migration 21) in one spelling: each dialect gives
/// its JSON reads (the plan's name and operator, the rule, the reasons'
/// codes). The judged value is the instrument's K2 on a plan deciding on
/// K2, else k2_max with the U95 of the mounting it came from.
macro_rules! analyst_view {
    ($plan_name:literal, $operator:literal, $rule:literal, $reason_codes:literal) => {
        concat!(
            "CREATE VIEW analyst_results AS
    SELECT r.run_id, runs.station, runs.started_at, runs.utc_offset_s, runs.software_version,
        ", $plan_name, " AS plan_name,
        ", $operator, " AS operator,
        runs.retest_of,
        r.slot, r.serial, r.outcome, r.measurand,
        CASE r.measurand WHEN 'K2' THEN r.instrument_k2_ug_per_g2 ELSE r.k2_max_ug_per_g2 END
            AS judged_ug_per_g2,
        CASE r.measurand WHEN 'K2' THEN r.instrument_k2_u95
            ELSE CASE WHEN abs(coalesce(r.k2_p_ug_per_g2, 0)) >= abs(coalesce(r.k2_n_ug_per_g2, 0))
                THEN r.k2_p_u95 ELSE r.k2_n_u95 END
        END AS judged_u95,
        r.limit_ug_per_g2,
        ", $rule, " AS decision_rule,
        ", $reason_codes, " AS reason_codes,
        r.instrument_k2_ug_per_g2, r.instrument_k2_u95,
        r.k2_p_ug_per_g2, r.k2_p_u95, r.k2_n_ug_per_g2, r.k2_n_u95, r.k2_max_ug_per_g2,
        r.revision
    FROM results AS r JOIN runs ON runs.id = r.run_id;"
        )
    };
}

/// The analyst's view on SQLite (migration 21).
const MIGRATION_21_SQLITE: &str = analyst_view!(
    "json_extract(runs.plan_json, '$.name')",
    "json_extract(runs.plan_json, '$.operator')",
    "json_extract(r.record_json, '$.decision.rule')",
    "(SELECT group_concat(json_extract(reason.value, '$.code'), ',')
            FROM json_each(r.record_json, '$.reasons') AS reason)"
);

/// The analyst's view on PostgreSQL (migration 21), and what each table
/// holds said in the catalogue a DBA reads (psql's describe).
const MIGRATION_21_POSTGRES: &str = concat!(
    analyst_view!(
        "runs.plan_json->>'name'",
        "runs.plan_json->>'operator'",
        "r.record_json->'decision'->>'rule'",
        "(SELECT string_agg(reason.value->>'code', ',')
            FROM jsonb_array_elements(CASE jsonb_typeof(r.record_json->'reasons')
                WHEN 'array' THEN r.record_json->'reasons' ELSE '[]'::jsonb END) AS reason)"
    ),
    "
    COMMENT ON VIEW analyst_results IS 'One row per instrument and run: what its verdict judged (measurand K2 or k2_max, judged_ug_per_g2 with judged_u95 [µg/g²], against limit_ug_per_g2 by decision_rule guarded or simple), outcome, reason_codes (comma-separated), plan_name, operator. The analyst role reads this view only (spinbench migrate --grant-analyst ROLE).';
    COMMENT ON TABLE runs IS 'One row per run: its station, plan (jsonb), state, start and end, and the retest it is of.';
    COMMENT ON TABLE results IS 'One row per instrument of a run: its outcome, figures as columns (k2 per mounting, K2, U95 [µg/g²]) and the whole record (record_json).';
    COMMENT ON TABLE points IS 'One row per averaged point: an instrument at a level in a mounting and direction.';
    COMMENT ON TABLE units IS 'The instruments of each run, by slot (numbered from 1).';
    COMMENT ON TABLE values_1s IS 'Every one-second value of every instrument (pruned into Parquet archives by spinbench prune).';
    COMMENT ON TABLE events IS 'The run''s event log as the engine sent it (pruned with the values).';
    COMMENT ON TABLE operator_actions IS 'What the operator was asked and answered, with its wording.';
    COMMENT ON TABLE run_notices IS 'A run''s notices and faults, kept with its record.';
    COMMENT ON TABLE stations IS 'The fleet: each station''s identity and heartbeat.';
    COMMENT ON TABLE equipment IS 'Each station''s equipment register: identity, certificate, calibration and due dates.';
    COMMENT ON TABLE audit IS 'Who did what on the web and the command line (append-only).';
    COMMENT ON TABLE users IS 'The web''s users: password hashes; no analyst reads it.';
    COMMENT ON TABLE sessions IS 'Web sessions (hashed tokens): no analyst reads it.';
    COMMENT ON TABLE spinbench_migrations IS 'The store''s migrations, each with its release.';
    COMMENT ON COLUMN results.instrument_k2_ug_per_g2 IS 'The instrument''s own K2 = (k2_P - k2_N)/2 [µg/g²] (docs/method.md (15)).';
    COMMENT ON COLUMN results.instrument_k2_u95 IS 'Its expanded uncertainty at 95 % [µg/g²].';
    COMMENT ON COLUMN results.measurand IS 'What the verdict judged: K2 or k2_max.';
    COMMENT ON COLUMN results.limit_ug_per_g2 IS 'The plan''s limit on it [µg/g²].';"
);

/// Migration 17 on SQLite: the register's key changes, so its table is
/// made again (it holds one row per device). Each station the store knew
/// (in `stations` or a run) gets a copy of the one shared register (an
/// engineer then corrects each station's entries); a store that knew none
/// keeps its entries under the station '' (listed by `spinbench equipment
/// list`, used by no station).
const MIGRATION_17_SQLITE: &str = "CREATE TABLE equipment_by_station (
        station TEXT NOT NULL,
        role TEXT NOT NULL,
        identity TEXT NOT NULL,
        certificate TEXT NOT NULL,
        calibrated_on TEXT NOT NULL,
        due_on TEXT NOT NULL,
        updated_by TEXT NOT NULL,
        updated_at INTEGER NOT NULL,
        PRIMARY KEY (station, role)
    );
    INSERT INTO equipment_by_station
        SELECT s.name, e.role, e.identity, e.certificate, e.calibrated_on, e.due_on, e.updated_by, e.updated_at
        FROM equipment e, (SELECT name FROM stations UNION SELECT station FROM runs) s;
    INSERT INTO equipment_by_station
        SELECT '', role, identity, certificate, calibrated_on, due_on, updated_by, updated_at FROM equipment
        WHERE NOT EXISTS (SELECT 1 FROM stations) AND NOT EXISTS (SELECT 1 FROM runs);
    DROP TABLE equipment;
    ALTER TABLE equipment_by_station RENAME TO equipment;
    ALTER TABLE stations ADD COLUMN instance_id TEXT;
    ALTER TABLE stations ADD COLUMN kind TEXT;
    ALTER TABLE stations ADD COLUMN retired_at INTEGER;
    ALTER TABLE results ADD COLUMN revision INTEGER NOT NULL DEFAULT 0;";

/// Migration 17 on PostgreSQL: the key changes in place; the role and the
/// station's kind are checked (NOT VALID, as migration 13's checks).
const MIGRATION_17_POSTGRES: &str = "ALTER TABLE equipment ADD COLUMN station TEXT NOT NULL DEFAULT '';
    ALTER TABLE equipment DROP CONSTRAINT equipment_pkey;
    INSERT INTO equipment (station, role, identity, certificate, calibrated_on, due_on, updated_by, updated_at)
        SELECT s.name, e.role, e.identity, e.certificate, e.calibrated_on, e.due_on, e.updated_by, e.updated_at
        FROM equipment e CROSS JOIN (SELECT name FROM stations UNION SELECT station FROM runs) s
        WHERE e.station = '';
    DELETE FROM equipment WHERE station = '' AND (EXISTS (SELECT 1 FROM stations) OR EXISTS (SELECT 1 FROM runs));
    ALTER TABLE equipment ALTER COLUMN station DROP DEFAULT;
    ALTER TABLE equipment ADD PRIMARY KEY (station, role);
    ALTER TABLE equipment ADD CONSTRAINT equipment_role_known CHECK (role IN ('centrifuge', 'instrument supply', 'module supply')
        OR role ~ '^fmu [1-9][0-9]?$') NOT VALID;
    ALTER TABLE stations ADD COLUMN instance_id TEXT, ADD COLUMN kind TEXT, ADD COLUMN retired_at timestamptz;
    ALTER TABLE stations ADD CONSTRAINT stations_kind_known CHECK (kind IN ('server', 'command line')) NOT VALID;
    ALTER TABLE results ADD COLUMN revision BIGINT NOT NULL DEFAULT 0;";

/// Migration 16: every stored slot one up. In two steps (through the
/// negative numbers), since a key is checked row by row and `slot + 1`
/// would meet the next row's slot on the way.
const MIGRATION_16: &str = "UPDATE points SET slot = -(slot + 1);
    UPDATE points SET slot = -slot;
    UPDATE results SET slot = -(slot + 1);
    UPDATE results SET slot = -slot;
    UPDATE units SET slot = -(slot + 1);
    UPDATE units SET slot = -slot;
    UPDATE values_1s SET slot = -(slot + 1);
    UPDATE values_1s SET slot = -slot;";

/// Migration 15 on PostgreSQL: each column to its own type. A JSON text
/// that is not JSON (never written by the station) becomes NULL in a
/// column that may be NULL; a NUL escape, which jsonb cannot hold, becomes
/// U+FFFD. Times were Unix seconds.
const MIGRATION_15_POSTGRES: &str = "CREATE OR REPLACE FUNCTION pg_temp.spinbench_jsonb(t TEXT) RETURNS jsonb LANGUAGE plpgsql AS
        $f$ BEGIN RETURN replace(t, '\\u0000', '\\ufffd')::jsonb; EXCEPTION WHEN others THEN RETURN NULL; END $f$;
    ALTER TABLE runs ALTER COLUMN started_at TYPE timestamptz USING to_timestamp(started_at),
        ALTER COLUMN finished_at TYPE timestamptz USING to_timestamp(finished_at),
        ALTER COLUMN plan_json TYPE jsonb USING coalesce(pg_temp.spinbench_jsonb(plan_json), 'null'::jsonb),
        ALTER COLUMN devices_json TYPE jsonb USING pg_temp.spinbench_jsonb(devices_json),
        ALTER COLUMN reason_wording TYPE jsonb USING pg_temp.spinbench_jsonb(reason_wording);
    ALTER TABLE results ALTER COLUMN record_json TYPE jsonb USING coalesce(pg_temp.spinbench_jsonb(record_json), 'null'::jsonb);
    ALTER TABLE events ALTER COLUMN at TYPE timestamptz USING to_timestamp(at),
        ALTER COLUMN json TYPE jsonb USING coalesce(pg_temp.spinbench_jsonb(json), 'null'::jsonb);
    ALTER TABLE operator_actions ALTER COLUMN at TYPE timestamptz USING to_timestamp(at);
    ALTER TABLE values_1s ALTER COLUMN on_speed TYPE boolean USING on_speed <> 0;
    ALTER TABLE stations ALTER COLUMN first_seen TYPE timestamptz USING to_timestamp(first_seen),
        ALTER COLUMN last_seen TYPE timestamptz USING to_timestamp(last_seen);
    ALTER TABLE users ALTER COLUMN created_at TYPE timestamptz USING to_timestamp(created_at);
    ALTER TABLE audit ALTER COLUMN at TYPE timestamptz USING to_timestamp(at);
    ALTER TABLE sessions ALTER COLUMN last_seen TYPE timestamptz USING to_timestamp(last_seen);
    ALTER TABLE equipment ALTER COLUMN calibrated_on TYPE date USING calibrated_on::date,
        ALTER COLUMN due_on TYPE date USING due_on::date,
        ALTER COLUMN updated_at TYPE timestamptz USING to_timestamp(updated_at);";

/// Migration 14 on SQLite. SQLite cannot add a foreign key to a table
/// that exists (it would rebuild every large table): its references stay
/// those the tables were made with (points, results, units → runs).
const MIGRATION_14_SQLITE: &str = "ALTER TABLE runs ADD COLUMN record_version INTEGER;
    ALTER TABLE results ADD COLUMN k2_p_ug_per_g2 REAL;
    ALTER TABLE results ADD COLUMN k2_p_u95 REAL;
    ALTER TABLE results ADD COLUMN k2_n_ug_per_g2 REAL;
    ALTER TABLE results ADD COLUMN k2_n_u95 REAL;
    ALTER TABLE results ADD COLUMN instrument_k2_ug_per_g2 REAL;
    ALTER TABLE results ADD COLUMN instrument_k2_u95 REAL;
    ALTER TABLE results ADD COLUMN measurand TEXT;
    ALTER TABLE results ADD COLUMN limit_ug_per_g2 REAL;
    UPDATE results SET
        k2_p_ug_per_g2 = json_extract(record_json, '$.analysis.fits.P.k2_ug_per_g2'),
        k2_p_u95 = json_extract(record_json, '$.analysis.fits.P.uncertainty.k2_ug_per_g2.U95'),
        k2_n_ug_per_g2 = json_extract(record_json, '$.analysis.fits.N.k2_ug_per_g2'),
        k2_n_u95 = json_extract(record_json, '$.analysis.fits.N.uncertainty.k2_ug_per_g2.U95'),
        instrument_k2_ug_per_g2 = json_extract(record_json, '$.analysis.joint.k2_even_ug_per_g2'),
        instrument_k2_u95 = json_extract(record_json, '$.analysis.joint.k2_even_U95'),
        measurand = json_extract(record_json, '$.decision.measurand'),
        limit_ug_per_g2 = json_extract(record_json, '$.decision.limit_ug_per_g2')
    WHERE json_valid(record_json);
    CREATE INDEX results_outcome ON results (outcome, run_id);";

/// Migration 14 on PostgreSQL. A record that is not JSON is left without
/// figures (never a failed upgrade); the keys are NOT VALID, as the checks
/// of migration 13: rows already stored are not re-checked, new ones are.
const MIGRATION_14_POSTGRES: &str = "ALTER TABLE runs ADD COLUMN record_version BIGINT;
    ALTER TABLE results ADD COLUMN k2_p_ug_per_g2 DOUBLE PRECISION;
    ALTER TABLE results ADD COLUMN k2_p_u95 DOUBLE PRECISION;
    ALTER TABLE results ADD COLUMN k2_n_ug_per_g2 DOUBLE PRECISION;
    ALTER TABLE results ADD COLUMN k2_n_u95 DOUBLE PRECISION;
    ALTER TABLE results ADD COLUMN instrument_k2_ug_per_g2 DOUBLE PRECISION;
    ALTER TABLE results ADD COLUMN instrument_k2_u95 DOUBLE PRECISION;
    ALTER TABLE results ADD COLUMN measurand TEXT;
    ALTER TABLE results ADD COLUMN limit_ug_per_g2 DOUBLE PRECISION;
    CREATE OR REPLACE FUNCTION pg_temp.spinbench_jsonb(t TEXT) RETURNS jsonb LANGUAGE plpgsql AS
        $f$ BEGIN RETURN t::jsonb; EXCEPTION WHEN others THEN RETURN NULL; END $f$;
    CREATE OR REPLACE FUNCTION pg_temp.spinbench_number(j jsonb) RETURNS DOUBLE PRECISION LANGUAGE sql AS
        $f$ SELECT CASE WHEN jsonb_typeof(j) = 'number' THEN (j #>> '{}')::double precision END $f$;
    UPDATE results r SET
        k2_p_ug_per_g2 = pg_temp.spinbench_number(j #> '{analysis,fits,P,k2_ug_per_g2}'),
        k2_p_u95 = pg_temp.spinbench_number(j #> '{analysis,fits,P,uncertainty,k2_ug_per_g2,U95}'),
        k2_n_ug_per_g2 = pg_temp.spinbench_number(j #> '{analysis,fits,N,k2_ug_per_g2}'),
        k2_n_u95 = pg_temp.spinbench_number(j #> '{analysis,fits,N,uncertainty,k2_ug_per_g2,U95}'),
        instrument_k2_ug_per_g2 = pg_temp.spinbench_number(j #> '{analysis,joint,k2_even_ug_per_g2}'),
        instrument_k2_u95 = pg_temp.spinbench_number(j #> '{analysis,joint,k2_even_U95}'),
        measurand = j #>> '{decision,measurand}',
        limit_ug_per_g2 = pg_temp.spinbench_number(j #> '{decision,limit_ug_per_g2}')
    FROM (SELECT run_id, slot, pg_temp.spinbench_jsonb(record_json) AS j FROM results) parsed
    WHERE parsed.run_id = r.run_id AND parsed.slot = r.slot AND parsed.j IS NOT NULL;
    CREATE INDEX results_outcome ON results (outcome, run_id);
    ALTER TABLE results ADD CONSTRAINT results_measurand_known CHECK (measurand IN ('K2', 'k2_max')) NOT VALID;
    ALTER TABLE events ADD CONSTRAINT events_run FOREIGN KEY (run_id) REFERENCES runs(id) NOT VALID;
    ALTER TABLE values_1s ADD CONSTRAINT values_1s_run FOREIGN KEY (run_id) REFERENCES runs(id) NOT VALID;
    ALTER TABLE operator_actions ADD CONSTRAINT operator_actions_run FOREIGN KEY (run_id) REFERENCES runs(id) NOT VALID;
    ALTER TABLE runs ADD CONSTRAINT runs_station FOREIGN KEY (station) REFERENCES stations(name) NOT VALID;
    ALTER TABLE runs ADD CONSTRAINT runs_retest_of_run FOREIGN KEY (retest_of) REFERENCES runs(id) NOT VALID;
    ALTER TABLE sessions ADD CONSTRAINT sessions_user FOREIGN KEY (user_name) REFERENCES users(name) ON DELETE CASCADE NOT VALID;";

/// The runs stored before labels were given are numbered as they started.
const MIGRATION_RUN_SEQ: &str = "ALTER TABLE runs ADD COLUMN seq INTEGER;
    UPDATE runs SET seq = (SELECT COUNT(*) FROM runs r2
        WHERE r2.station = runs.station AND r2.started_at / 86400 = runs.started_at / 86400
          AND (r2.started_at < runs.started_at OR (r2.started_at = runs.started_at AND r2.id <= runs.id)));";
const MIGRATION_RUN_SEQ_PG: &str = "ALTER TABLE runs ADD COLUMN seq BIGINT;
    UPDATE runs SET seq = (SELECT COUNT(*) FROM runs r2
        WHERE r2.station = runs.station AND r2.started_at / 86400 = runs.started_at / 86400
          AND (r2.started_at < runs.started_at OR (r2.started_at = runs.started_at AND r2.id <= runs.id)));";

const MIGRATION_1_SQLITE: &str = "CREATE TABLE runs (
        id TEXT PRIMARY KEY,
        station TEXT NOT NULL,
        plan_json TEXT NOT NULL,
        software_version TEXT NOT NULL,
        state TEXT NOT NULL,
        reason TEXT,
        started_at INTEGER NOT NULL,
        finished_at INTEGER,
        starts INTEGER NOT NULL DEFAULT 1
    );
    CREATE TABLE points (
        run_id TEXT NOT NULL REFERENCES runs(id),
        step INTEGER NOT NULL,
        slot INTEGER NOT NULL,
        serial TEXT NOT NULL,
        mount TEXT NOT NULL,
        g_nominal REAL NOT NULL,
        direction TEXT NOT NULL,
        g_applied REAL NOT NULL,
        rate_deg_s REAL NOT NULL,
        output_hz REAL NOT NULL,
        std_hz REAL NOT NULL,
        n INTEGER NOT NULL,
        t0_s REAL NOT NULL,
        t1_s REAL NOT NULL,
        PRIMARY KEY (run_id, step, slot)
    );
    CREATE TABLE results (
        run_id TEXT NOT NULL REFERENCES runs(id),
        slot INTEGER NOT NULL,
        serial TEXT NOT NULL,
        outcome TEXT NOT NULL,
        k2_max_ug_per_g2 REAL,
        record_json TEXT NOT NULL,
        PRIMARY KEY (run_id, slot)
    );
    CREATE INDEX results_serial ON results(serial);
    CREATE TABLE events (
        seq INTEGER PRIMARY KEY AUTOINCREMENT,
        run_id TEXT NOT NULL,
        at INTEGER NOT NULL,
        kind TEXT NOT NULL,
        json TEXT NOT NULL
    );";

const MIGRATION_2_SQLITE: &str = "CREATE TABLE values_1s (
        run_id TEXT NOT NULL,
        t_s REAL NOT NULL,
        slot INTEGER NOT NULL,
        output_hz REAL,
        rate_deg_s REAL NOT NULL,
        on_speed INTEGER NOT NULL,
        PRIMARY KEY (run_id, t_s, slot)
    ) WITHOUT ROWID;";
