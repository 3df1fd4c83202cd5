//! Just enough of the W3C WebDriver protocol to drive headless Chromium
//! through chromedriver: a session, navigation, elements, clicks, typing,
//! scripts and screenshots. Written here over the HTTP client the tests
//! already use: these are eight JSON calls, and a WebDriver crate would
//! bring an async runtime and a connector stack into the tests for them.

// Shared by the browser tests; each uses a part.
#![allow(dead_code)]

use base64::Engine;
use serde_json::{Value, json};
use std::net::TcpListener;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// chromedriver in a child process, with one browser session.
pub struct Browser {
    driver: Child,
    agent: ureq::Agent,
    session: String,
    base: String,
}

impl Drop for Browser {
    fn drop(&mut self) {
        let _ = self
            .agent
            .delete(format!("{}/session/{}", self.base, self.session))
            .call();
        let _ = self.driver.kill();
        let _ = self.driver.wait();
    }
}

fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .expect("a free port")
}

/// The element reference key of the W3C protocol.
const ELEMENT: &str = "element-6066-11e4-a52e-4f735466cecf";

impl Browser {
    /// Start chromedriver and a headless Chromium (`/usr/bin/chromium`).
    pub fn start() -> Browser {
        let port = free_port();
        let driver = Command::new("chromedriver")
            .arg(format!("--port={port}"))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("chromedriver runs (./scripts/test installs chromium and chromium-driver)");
        let agent: ureq::Agent = ureq::Agent::config_builder()
            .http_status_as_error(false)
            .timeout_global(Some(Duration::from_secs(60)))
            .build()
            .into();
        let base = format!("http://127.0.0.1:{port}");
        let until = Instant::now() + Duration::from_secs(20);
        while agent.get(format!("{base}/status")).call().is_err() {
            assert!(Instant::now() < until, "chromedriver did not start");
            std::thread::sleep(Duration::from_millis(100));
        }
        let caps = json!({"capabilities": {"alwaysMatch": {
            "browserName": "chrome",
            "goog:chromeOptions": {
                "binary": "/usr/bin/chromium",
                "args": ["--headless=new", "--no-sandbox", "--disable-gpu",
                         "--disable-dev-shm-usage", "--disable-background-networking",
                         "--no-first-run", "--window-size=1400,1100"]
            }
        }}});
        let mut response = agent
            .post(format!("{base}/session"))
            .send_json(&caps)
            .expect("new session");
        let reply: Value = response.body_mut().read_json().expect("json");
        let session = reply["value"]["sessionId"]
            .as_str()
            .unwrap_or_else(|| panic!("no browser session: {reply}"))
            .to_string();
        Browser {
            driver,
            agent,
            session,
            base,
        }
    }

    fn call(&self, method: &str, path: &str, body: Value) -> Value {
        self.try_call(method, path, body)
            .unwrap_or_else(|e| panic!("webdriver {method} {path}: {e}"))
    }

    /// As [`Browser::call`], the driver's error given back.
    fn try_call(&self, method: &str, path: &str, body: Value) -> Result<Value, Value> {
        let url = format!("{}/session/{}{}", self.base, self.session, path);
        let mut response = match method {
            "GET" => self.agent.get(&url).call(),
            _ => self.agent.post(&url).send_json(&body),
        }
        .expect("webdriver answers");
        let reply: Value = response.body_mut().read_json().expect("json");
        if reply["value"]["error"].is_string() {
            return Err(reply["value"].clone());
        }
        Ok(reply["value"].clone())
    }

    /// Open `url`.
    pub fn go(&self, url: &str) {
        self.call("POST", "/url", json!({ "url": url }));
    }

    /// Run `script` in the page; its return value.
    pub fn script(&self, script: &str) -> Value {
        self.call(
            "POST",
            "/execute/sync",
            json!({ "script": script, "args": [] }),
        )
    }

    /// Run an async `script` (it calls `arguments[0](result)`); the result.
    pub fn script_async(&self, script: &str) -> Value {
        self.call(
            "POST",
            "/execute/async",
            json!({ "script": script, "args": [] }),
        )
    }

    fn element(&self, css: &str) -> String {
        let v = self.call(
            "POST",
            "/element",
            json!({ "using": "css selector", "value": css }),
        );
        v[ELEMENT]
            .as_str()
            .unwrap_or_else(|| panic!("no element {css}: {v}"))
            .to_string()
    }

    /// Click the element `css`.
    /// The page may draw the element again between finding and clicking it
    /// (a table refilled by a refresh): a stale element is found again,
    /// for at most 5 s.
    pub fn click(&self, css: &str) {
        let until = Instant::now() + Duration::from_secs(5);
        loop {
            let id = self.element(css);
            match self.try_call("POST", &format!("/element/{id}/click"), json!({})) {
                Ok(_) => return,
                Err(e) if e["error"] == "stale element reference" && Instant::now() < until => {
                    std::thread::sleep(Duration::from_millis(100));
                }
                Err(e) => panic!("webdriver click {css}: {e}"),
            }
        }
    }

    /// Accept the page's `confirm()` (or `alert()`) dialog, waiting up to
    /// 5 s for the page to open it (the click that opens it may land a
    /// moment after the driver answered).
    pub fn accept_dialog(&self) {
        let until = Instant::now() + Duration::from_secs(5);
        loop {
            match self.try_call("POST", "/alert/accept", json!({})) {
                Ok(_) => return,
                Err(e) if e["error"] == "no such alert" && Instant::now() < until => {
                    std::thread::sleep(Duration::from_millis(100));
                }
                Err(e) => panic!("webdriver accept the dialog: {e}"),
            }
        }
    }

    /// Dismiss (cancel) the page's `confirm()` dialog, waiting up to 5 s
    /// for the page to open it.
    pub fn dismiss_dialog(&self) {
        let until = Instant::now() + Duration::from_secs(5);
        loop {
            match self.try_call("POST", "/alert/dismiss", json!({})) {
                Ok(_) => return,
                Err(e) if e["error"] == "no such alert" && Instant::now() < until => {
                    std::thread::sleep(Duration::from_millis(100));
                }
                Err(e) => panic!("webdriver dismiss the dialog: {e}"),
            }
        }
    }

    /// Click the prompt's Abort and cancel its confirmation:
    /// the run must still wait at its prompt.
    pub fn cancel_the_prompts_abort(&self) {
        self.click("#prompt-abort");
        self.dismiss_dialog();
        std::thread::sleep(Duration::from_millis(300));
        assert_eq!(
            self.script("return !document.getElementById('prompt').hidden"),
            Value::Bool(true),
            "a cancelled Abort left the prompt"
        );
    }

    /// Type `text` into the element `css`, after clearing it. As with
    /// [`Browser::click`], an element the page drew again meanwhile is
    /// found again, for at most 5 s.
    pub fn type_into(&self, css: &str, text: &str) {
        let until = Instant::now() + Duration::from_secs(5);
        loop {
            let id = self.element(css);
            let typed = self
                .try_call("POST", &format!("/element/{id}/clear"), json!({}))
                .and_then(|_| {
                    self.try_call(
                        "POST",
                        &format!("/element/{id}/value"),
                        json!({ "text": text }),
                    )
                });
            match typed {
                Ok(_) => return,
                // Drawn again, or not shown yet (a page that just opened).
                Err(e)
                    if (e["error"] == "stale element reference"
                        || e["error"] == "element not interactable")
                        && Instant::now() < until =>
                {
                    std::thread::sleep(Duration::from_millis(100));
                }
                Err(e) => panic!("webdriver type into {css}: {e}"),
            }
        }
    }

    /// Wait (at most `seconds`) until `script` returns true.
    pub fn wait_for(&self, seconds: u64, what: &str, script: &str) {
        let until = Instant::now() + Duration::from_secs(seconds);
        loop {
            if self.script(script) == Value::Bool(true) {
                return;
            }
            if Instant::now() >= until {
                // What the page showed, so a failure on CI can be read
                // without its screenshots.
                let shown = self.script(
                    "return [...document.querySelectorAll('section:not([hidden]), #alarm, #message')]\
                     .map((e) => '[' + e.id + '] ' + e.innerText).join('\\n').slice(0, 4000)",
                );
                panic!(
                    "waited {seconds} s for {what}; the page showed:\n{}",
                    shown.as_str().unwrap_or_default()
                );
            }
            std::thread::sleep(Duration::from_millis(100));
        }
    }

    /// Resize the window (a phone: 400 × 800).
    pub fn set_window(&self, width: u32, height: u32) {
        self.call(
            "POST",
            "/window/rect",
            json!({ "width": width, "height": height }),
        );
    }

    /// A PNG screenshot of the window.
    pub fn screenshot(&self, path: &std::path::Path) {
        let data = self.call("GET", "/screenshot", Value::Null);
        let png = base64::engine::general_purpose::STANDARD
            .decode(data.as_str().expect("base64"))
            .expect("png");
        std::fs::write(path, png).expect("write screenshot");
    }
}
