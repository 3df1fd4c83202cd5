//! A `spinbench serve --simulate` in a child process, and a small JSON
//! client for its API (cookie and CSRF token kept like a browser keeps them).

// Shared by the API and the browser tests; each uses a part.
#![allow(dead_code)]

use serde_json::Value;
use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};

/// A short plan (±6 g in both mountings, 3 s dwell) named `title`, with
/// `serials` in slots 1, 2, ….
pub fn short_plan(title: &str, serials: &[&str]) -> String {
    let mut text = format!(
        "name = \"{title}\"\nrange_g = 6\nlevels = [0, 1, 2, 3, 4, 6]\npasses = [\"P\", \"N\"]\n\
         warmup_s = 0\ndwell = {{ seconds = 3 }}\nstability = {{ hold_s = 3 }}\n[serials]\n"
    );
    for (i, serial) in serials.iter().enumerate() {
        text.push_str(&format!("{} = \"{serial}\"\n", i + 1));
    }
    text
}

/// A running server; killed when dropped.
pub struct Server {
    child: Child,
    /// `http://127.0.0.1:PORT` (`https://` under `--tls-cert`).
    pub base: String,
}

impl Server {
    /// The server's process id.
    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// Ask the server to stop (SIGTERM), as a service manager does.
    pub fn terminate(&self) {
        let _ = Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status();
    }

    /// Wait at most `limit` for the server to exit; its status if it did.
    pub fn wait_exit(&mut self, limit: std::time::Duration) -> Option<std::process::ExitStatus> {
        let until = std::time::Instant::now() + limit;
        while std::time::Instant::now() < until {
            if let Ok(Some(status)) = self.child.try_wait() {
                return Some(status);
            }
            std::thread::sleep(std::time::Duration::from_millis(50));
        }
        None
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The store a test's server keeps: SQLite in its data directory, or a
/// fresh database on the test PostgreSQL server (`SPINBENCH_TEST_POSTGRES`,
/// started by `scripts/test`). Every web test runs on both.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Backend {
    /// `DATA/spinbench.db`.
    Sqlite,
    /// A fresh PostgreSQL database.
    Postgres,
    /// A fresh PostgreSQL database reached through PgBouncer in
    /// transaction pooling.
    PgBouncer,
}

/// Where `data`'s store is written down for [`store_of`].
const STORE_URL_FILE: &str = "test-store-url";

impl Backend {
    /// Make `data`'s store on this back end: every later [`add_user`] and
    /// [`serve`] on `data` uses it.
    pub fn prepare(self, data: &Path) {
        if self != Backend::Sqlite {
            let admin = spinbench_store::testing::postgres_url().unwrap_or_else(|e| panic!("{e}"));
            let mut url = spinbench_store::testing::fresh_postgres_database(&admin)
                .expect("a fresh PostgreSQL database");
            if self == Backend::PgBouncer {
                url = spinbench_store::testing::behind_pgbouncer(&url)
                    .unwrap_or_else(|e| panic!("{e}"));
            }
            std::fs::write(data.join(STORE_URL_FILE), url).expect("write the store's URL");
        }
    }
}

/// Let `other` keep the same store as `data` (two servers of a fleet): its
/// PostgreSQL database, or its SQLite file.
pub fn share_store(data: &Path, other: &Path) {
    let url = std::fs::read_to_string(data.join(STORE_URL_FILE))
        .unwrap_or_else(|_| data.join("spinbench.db").display().to_string());
    std::fs::write(other.join(STORE_URL_FILE), url).expect("write the store's URL");
}

/// The store `data`'s server keeps: the `--db` argument.
pub fn store_of(data: &Path) -> std::ffi::OsString {
    match std::fs::read_to_string(data.join(STORE_URL_FILE)) {
        Ok(url) => url.trim().into(),
        Err(_) => data.join("spinbench.db").into_os_string(),
    }
}

/// Add a user through the command line (as the first admin is made).
pub fn add_user(data: &Path, name: &str, role: &str, password: &str) {
    let out = Command::new(env!("CARGO_BIN_EXE_spinbench"))
        .args(["user", "add", name, "--role", role, "--db"])
        .arg(store_of(data))
        .env("SPINBENCH_PASSWORD", password)
        .output()
        .expect("spinbench user add");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Start `spinbench serve --simulate` on a free loopback port.
pub fn serve(data: &Path, sim_speed: &str) -> Server {
    serve_with(data, sim_speed, &[])
}

/// As [`serve`], with more options.
pub fn serve_with(data: &Path, sim_speed: &str, extra: &[&str]) -> Server {
    spawn_server(data, sim_speed, extra, Stdio::inherit())
}

/// As [`serve_with`], the server's standard error written to `log` (to look
/// for panics in it).
pub fn serve_logged(data: &Path, sim_speed: &str, extra: &[&str], log: &Path) -> Server {
    let file = std::fs::File::create(log).expect("the server's log file");
    spawn_server(data, sim_speed, extra, Stdio::from(file))
}

fn spawn_server(data: &Path, sim_speed: &str, extra: &[&str], stderr: Stdio) -> Server {
    spawn_serve(
        data,
        &["--simulate", "--sim-speed", sim_speed],
        extra,
        stderr,
    )
}

/// `spinbench serve --station CONFIG` (real devices, as the config says) on
/// a free loopback port.
pub fn serve_station(data: &Path, station: &Path) -> Server {
    let station = station.to_str().expect("a UTF-8 path");
    spawn_serve(data, &["--station", station], &[], Stdio::inherit())
}

fn spawn_serve(data: &Path, mode: &[&str], extra: &[&str], stderr: Stdio) -> Server {
    let mut child = Command::new(env!("CARGO_BIN_EXE_spinbench"))
        .arg("serve")
        .args(mode)
        .args(["--bind", "127.0.0.1:0", "--data"])
        .arg(data)
        .arg("--db")
        .arg(store_of(data))
        .args(extra)
        .stdout(Stdio::piped())
        .stderr(stderr)
        .spawn()
        .expect("spinbench serve");
    let stdout = child.stdout.take().expect("stdout");
    let mut lines = BufReader::new(stdout).lines();
    let base = loop {
        let line = lines
            .next()
            .expect("the server said where it listens")
            .expect("a line");
        // Its own line, not a warning that names another's address.
        let Some(said) = line.strip_prefix("spinbench serve: ") else {
            continue;
        };
        let scheme = ["https://", "http://"]
            .into_iter()
            .find_map(|s| said.split(s).nth(1).map(|rest| (s, rest)));
        if let Some((scheme, rest)) = scheme {
            let addr = rest.split('/').next().expect("address");
            break format!("{scheme}{addr}");
        }
    };
    // Keep reading its output so it never blocks on a full pipe.
    std::thread::spawn(move || for _ in lines {});
    Server { child, base }
}

/// A client with a session (after `login`).
pub struct Client {
    agent: ureq::Agent,
    base: String,
    /// The session cookie (`name=value`).
    pub cookie: Option<String>,
    /// The CSRF token.
    pub csrf: Option<String>,
    /// An API token's secret, sent as `Authorization: Bearer` (a machine
    /// client: no cookie, no CSRF token).
    pub bearer: Option<String>,
}

/// A response: status, `Set-Cookie`, content type, body text.
#[derive(Debug)]
pub struct Reply {
    /// HTTP status.
    pub status: u16,
    /// The `Set-Cookie` header, if any.
    pub set_cookie: Option<String>,
    /// The `Content-Type` header.
    pub content_type: String,
    /// The `Retry-After` header, if any.
    pub retry_after: Option<String>,
    /// The `Link` header, if any.
    pub link: Option<String>,
    /// The body.
    pub body: Vec<u8>,
}

impl Reply {
    /// The body as JSON (Null if it is not).
    pub fn json(&self) -> Value {
        serde_json::from_slice(&self.body).unwrap_or(Value::Null)
    }
}

impl Client {
    /// A client without a session.
    pub fn new(server: &Server) -> Client {
        let agent: ureq::Agent = ureq::Agent::config_builder()
            .http_status_as_error(false)
            .build()
            .into();
        Client::with_agent(server, agent)
    }

    /// A client without a session that sends through `agent` (e.g. one
    /// that trusts a test's own certificate).
    pub fn with_agent(server: &Server, agent: ureq::Agent) -> Client {
        Client {
            agent,
            base: server.base.clone(),
            cookie: None,
            csrf: None,
            bearer: None,
        }
    }

    /// The same session, sent to `server` from now on (a restarted server).
    pub fn moved_to(&mut self, server: &Server) {
        self.base = server.base.clone();
    }

    /// Log in; panics unless it succeeds.
    pub fn login(server: &Server, user: &str, password: &str) -> Client {
        Client::new(server).log_in(user, password)
    }

    /// This client logged in; panics unless it succeeds.
    pub fn log_in(mut self, user: &str, password: &str) -> Client {
        let c = &mut self;
        let r = c.send(
            "POST",
            "/api/login",
            Some(&serde_json::json!({"user": user, "password": password}).to_string()),
        );
        assert_eq!(r.status, 200, "login {user}: {:?}", r.json());
        let cookie = r.set_cookie.clone().expect("a session cookie");
        c.cookie = Some(cookie.split(';').next().unwrap_or("").to_string());
        c.csrf = r.json()["csrf"].as_str().map(str::to_string);
        self
    }

    /// Send a request (with the cookie and CSRF token, when held).
    pub fn send(&mut self, method: &str, path: &str, body: Option<&str>) -> Reply {
        self.send_with(method, path, body, true)
    }

    /// Send a request; `csrf` false leaves the token out.
    pub fn send_with(&mut self, method: &str, path: &str, body: Option<&str>, csrf: bool) -> Reply {
        let url = format!("{}{}", self.base, path);
        // A GET or DELETE carries no body (a server may close a connection
        // whose body it did not read, and the pool would reuse it).
        let body = body.filter(|_| !matches!(method, "GET" | "DELETE"));
        let mut request = ureq::http::Request::builder().method(method).uri(&url);
        if let Some(c) = &self.cookie {
            request = request.header("Cookie", c);
        }
        if csrf && let Some(t) = &self.csrf {
            request = request.header("X-CSRF-Token", t);
        }
        if let Some(secret) = &self.bearer {
            request = request.header("Authorization", format!("Bearer {secret}"));
        }
        if let Some(b) = body {
            // A plan or station config is TOML text, as the web UI sends
            // it, unless it is sent as a JSON object.
            let toml = method == "PUT"
                && (path.starts_with("/api/plans/") || path == "/api/station")
                && !b.trim_start().starts_with('{');
            let content_type = if toml {
                "text/plain; charset=utf-8"
            } else {
                "application/json"
            };
            request = request.header("Content-Type", content_type);
        }
        let request = request
            .body(body.unwrap_or("").as_bytes().to_vec())
            .expect("request");
        let mut response = self
            .agent
            .run(request)
            .unwrap_or_else(|e| panic!("{method} {path}: the server does not answer: {e}"));
        let header = |name: &str| {
            response
                .headers()
                .get(name)
                .and_then(|v| v.to_str().ok())
                .map(str::to_string)
        };
        let set_cookie = header("set-cookie");
        let content_type = header("content-type").unwrap_or_default();
        let retry_after = header("retry-after");
        let link = header("link");
        let status = response.status().as_u16();
        let body = response
            .body_mut()
            .with_config()
            .limit(200_000_000)
            .read_to_vec()
            .unwrap_or_default();
        let reply = Reply {
            status,
            set_cookie,
            content_type,
            retry_after,
            link,
            body,
        };
        // Every JSON answer of every web test is held to the document:
        // the schema of its operation and status.
        if reply.content_type.starts_with("application/json") && path != "/api/openapi.json" {
            self.check_against_document(method, path, &reply);
        }
        reply
    }

    /// Panic unless `reply`, a JSON answer to `method path`, matches the
    /// schema the server's OpenAPI document gives that operation and
    /// status (an operation or status the document does not list is not
    /// checked here; Schemathesis checks those).
    fn check_against_document(&mut self, method: &str, path: &str, reply: &Reply) {
        let doc = DOCUMENT.get_or_init(|| {
            let r = self
                .agent
                .get(format!("{}/api/openapi.json", self.base))
                .call()
                .and_then(|mut r| r.body_mut().read_to_string())
                .unwrap_or_else(|e| panic!("the OpenAPI document: {e}"));
            serde_json::from_str(&r).expect("the document is JSON")
        });
        let path = path.split('?').next().unwrap_or(path);
        let Some(template) = template_of(doc, path) else {
            return;
        };
        let method = method.to_ascii_lowercase();
        let status = reply.status.to_string();
        let schema = &doc["paths"][template.as_str()][method.as_str()]["responses"]
            [status.as_str()]["content"]["application/json"]["schema"];
        if schema.is_null() {
            return;
        }
        let key = format!("{method} {template} {status}");
        let validator = {
            let mut cache = VALIDATORS.lock().unwrap_or_else(|e| e.into_inner());
            cache
                .entry(key.clone())
                .or_insert_with(|| {
                    let mut whole = schema.clone();
                    whole["$schema"] = "https://json-schema.org/draft/2020-12/schema".into();
                    whole["components"] = doc["components"].clone();
                    std::sync::Arc::new(
                        jsonschema::validator_for(&whole).expect("the document's schema compiles"),
                    )
                })
                .clone()
        };
        let value: Value = serde_json::from_slice(&reply.body)
            .unwrap_or_else(|e| panic!("{key}: a JSON answer that is not JSON: {e}"));
        let errors: Vec<String> = validator
            .iter_errors(&value)
            .map(|e| format!("{e} at {}", e.instance_path))
            .collect();
        assert!(
            errors.is_empty(),
            "{key}: the answer does not match the document:\n{}\n{value}",
            errors.join("\n")
        );
        CHECKED.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    }

    /// GET and the JSON body (asserting the status).
    pub fn get_json(&mut self, path: &str, status: u16) -> Value {
        let r = self.send("GET", path, None);
        assert_eq!(r.status, status, "GET {path}: {:?}", r.json());
        r.json()
    }

    /// Answer "go on" at every prompt of the run `run_id` until it ends;
    /// how many prompts it asked.
    pub fn answer_prompts_until_end(&mut self, run_id: &str) -> usize {
        let mut prompts = 0;
        loop {
            let s = self.wait_status(120, |s| {
                s["prompt"].is_string() || s["active"].is_null() && s["run_id"] == run_id
            });
            if s["active"].is_null() {
                return prompts;
            }
            let r = self.send("POST", "/api/run/prompt", Some(r#"{"proceed": true}"#));
            assert_eq!(r.status, 200, "{:?}", r.json());
            prompts += 1;
            assert!(prompts < 10, "too many prompts");
        }
    }

    /// Poll `/api/status` until `done` holds (at most `seconds`).
    pub fn wait_status(&mut self, seconds: u64, done: impl Fn(&Value) -> bool) -> Value {
        let until = std::time::Instant::now() + std::time::Duration::from_secs(seconds);
        loop {
            let s = self.get_json("/api/status", 200);
            if done(&s) {
                return s;
            }
            assert!(
                std::time::Instant::now() < until,
                "status did not arrive in {seconds} s: {s}"
            );
            std::thread::sleep(std::time::Duration::from_millis(100));
        }
    }
}

/// The server's OpenAPI document, fetched once per test process.
static DOCUMENT: std::sync::OnceLock<Value> = std::sync::OnceLock::new();

/// Each operation's answer schema, compiled once.
static VALIDATORS: std::sync::Mutex<
    std::collections::BTreeMap<String, std::sync::Arc<jsonschema::Validator>>,
> = std::sync::Mutex::new(std::collections::BTreeMap::new());

/// How many answers were checked against the document.
pub static CHECKED: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

/// The document's path template `path` is an instance of (`/api/runs/x` →
/// `/api/runs/{id}`), literal segments before parameters.
fn template_of(doc: &Value, path: &str) -> Option<String> {
    let parts: Vec<&str> = path.split('/').collect();
    let mut best: Option<(usize, &String)> = None;
    for template in doc["paths"].as_object()?.keys() {
        let t: Vec<&str> = template.split('/').collect();
        if t.len() != parts.len() {
            continue;
        }
        let mut literal = 0;
        let fits = t.iter().zip(&parts).all(|(a, b)| {
            if a.starts_with('{') && a.ends_with('}') {
                !b.is_empty()
            } else {
                literal += 1;
                a == b
            }
        });
        if fits && best.is_none_or(|(l, _)| literal > l) {
            best = Some((literal, template));
        }
    }
    best.map(|(_, t)| t.clone())
}

/// Check `value` against the schema `name` of the server's own OpenAPI
/// document (JSON Schema 2020-12, its `$ref`s resolved in the document),
/// by the jsonschema crate; panics naming every mismatch and `what`.
pub fn matches_document(client: &mut Client, name: &str, value: &Value, what: &str) {
    let errors = document_errors(client, name, value);
    assert!(
        errors.is_empty(),
        "{what}: the answer does not match the document's {name}:\n{}\n{value}",
        errors.join("\n")
    );
}

/// What in `value` the schema `name` of the server's OpenAPI document refuses.
pub fn document_errors(client: &mut Client, name: &str, value: &Value) -> Vec<String> {
    let doc = client.get_json("/api/openapi.json", 200);
    let schema = serde_json::json!({
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "components": doc["components"],
        "$ref": format!("#/components/schemas/{name}"),
    });
    let validator = jsonschema::validator_for(&schema).expect("the document's schema compiles");
    validator
        .iter_errors(value)
        .map(|e| format!("{} at {}", e, e.instance_path))
        .collect()
}
