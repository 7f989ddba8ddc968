//! The local web server (axum): the page and its scripts from the binary, and the
//! JSON requests of the page.

use std::net::SocketAddr;
use std::sync::mpsc::Sender;
use std::sync::Arc;
use std::time::Instant;

use axum::body::Bytes;
use axum::extract::{Path, Query, State};
use axum::http::{header, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use axum::{Json, Router};
use serde::Deserialize;
use serde_json::{json, Value};

use crate::master::{Cmd, Hold, Job, ScopeRequest, Shared};

#[derive(Clone)]
struct App {
    shared: Arc<Shared>,
    jobs: Sender<Job>,
}

/// Every file of the page, served from the binary.
const FILES: [(&str, &str, &str); 5] = [
    (
        "index.html",
        "text/html; charset=utf-8",
        include_str!("../web/index.html"),
    ),
    ("app.js", "text/javascript", include_str!("../web/app.js")),
    ("style.css", "text/css", include_str!("../web/style.css")),
    (
        "uPlot.iife.min.js",
        "text/javascript",
        include_str!("../web/uplot/uPlot.iife.min.js"),
    ),
    (
        "uPlot.min.css",
        "text/css",
        include_str!("../web/uplot/uPlot.min.css"),
    ),
];

async fn file(Path(name): Path<String>) -> Response {
    match FILES.iter().find(|f| f.0 == name) {
        Some(&(_, mime, body)) => ([(header::CONTENT_TYPE, mime)], body).into_response(),
        None => StatusCode::NOT_FOUND.into_response(),
    }
}

async fn index() -> Response {
    file(Path("index.html".into())).await
}

async fn state(State(app): State<App>) -> Json<Value> {
    let v = app
        .shared
        .view
        .lock()
        .unwrap_or_else(|p| p.into_inner())
        .clone();
    Json(json!(v))
}

/// Sends a request to the master and waits for its answer.
async fn ask(app: &App, cmd: Cmd) -> Response {
    let (tx, rx) = tokio::sync::oneshot::channel();
    if app.jobs.send((cmd, tx)).is_err() {
        return (
            StatusCode::SERVICE_UNAVAILABLE,
            Json(json!({"error": "the master stopped"})),
        )
            .into_response();
    }
    match rx.await {
        Ok(Ok(v)) => Json(json!({ "ok": v })).into_response(),
        Ok(Err(e)) => Json(json!({ "error": e })).into_response(),
        Err(_) => Json(json!({"error": "the segment restarted meanwhile"})).into_response(),
    }
}

#[derive(Deserialize)]
struct DriveQ {
    drive: usize,
    index: Option<String>,
}

fn parse_index(s: &str) -> Option<u16> {
    let s = s.trim();
    match s.strip_prefix("0x").or_else(|| s.strip_prefix("0X")) {
        Some(h) => u16::from_str_radix(h, 16).ok(),
        None => s.parse().ok(),
    }
}

async fn objects(State(app): State<App>, Query(q): Query<DriveQ>) -> Response {
    match q.index.as_deref() {
        None => ask(&app, Cmd::Objects(q.drive)).await,
        Some(i) => match parse_index(i) {
            Some(i) => ask(&app, Cmd::Object(q.drive, i)).await,
            None => Json(json!({"error": format!("index '{i}'")})).into_response(),
        },
    }
}

#[derive(Deserialize)]
struct WriteReq {
    drive: usize,
    index: u16,
    sub: u8,
    value: String,
}

async fn write(State(app): State<App>, Json(w): Json<WriteReq>) -> Response {
    ask(&app, Cmd::Write(w.drive, w.index, w.sub, w.value)).await
}

#[derive(Deserialize)]
struct StoreReq {
    drive: usize,
    load: bool,
}

async fn store(State(app): State<App>, Json(s): Json<StoreReq>) -> Response {
    ask(&app, Cmd::Store(s.drive, s.load)).await
}

async fn history(State(app): State<App>, Query(q): Query<DriveQ>) -> Response {
    ask(&app, Cmd::History(q.drive)).await
}

#[derive(Deserialize)]
struct ScopeReq {
    drive: usize,
    #[serde(flatten)]
    req: ScopeRequest,
}

async fn scope(State(app): State<App>, Json(s): Json<ScopeReq>) -> Response {
    ask(&app, Cmd::Scope(s.drive, s.req)).await
}

#[derive(Deserialize)]
struct TuneReq {
    drive: usize,
    servo: Option<bool>,
}

async fn tune(State(app): State<App>, Json(t): Json<TuneReq>) -> Response {
    match t.servo {
        Some(servo) => ask(&app, Cmd::Tune(t.drive, servo)).await,
        None => ask(&app, Cmd::TuneResults(t.drive)).await,
    }
}

async fn update(State(app): State<App>, Query(q): Query<DriveQ>, body: Bytes) -> Response {
    ask(&app, Cmd::Update(q.drive, body.to_vec())).await
}

#[derive(Deserialize)]
struct HoldReq {
    drive: usize,
    enable: bool,
    dir: i8,
    speed: i32,
    mode: Option<i8>,
}

/// The dead-man: renewed by the page every 100 ms while "Enable" is on.
async fn hold(State(app): State<App>, Json(h): Json<HoldReq>) -> Json<Value> {
    let mut held = app.shared.hold.lock().unwrap_or_else(|p| p.into_inner());
    *held = h.enable.then_some(Hold {
        drive: h.drive,
        enable: true,
        dir: h.dir.signum(),
        speed: h.speed.clamp(0, 100_000),
        mode: h.mode.unwrap_or(3),
        at: Instant::now(),
    });
    Json(json!({"ok": true}))
}

/// Serves the page on `addr` until SIGINT / SIGTERM.
pub async fn serve(addr: SocketAddr, shared: Arc<Shared>, jobs: Sender<Job>) -> Result<(), String> {
    let app = App { shared, jobs };
    let router = Router::new()
        .route("/", get(index))
        .route("/static/{name}", get(file))
        .route("/api/state", get(state))
        .route("/api/objects", get(objects))
        .route("/api/write", post(write))
        .route("/api/store", post(store))
        .route("/api/history", get(history))
        .route("/api/scope", post(scope))
        .route("/api/tune", post(tune))
        .route("/api/update", post(update))
        .route("/api/hold", post(hold))
        .layer(axum::extract::DefaultBodyLimit::max(2 << 20))
        .with_state(app);
    let listener = tokio::net::TcpListener::bind(addr)
        .await
        .map_err(|e| format!("listen on {addr}: {e}"))?;
    let local = listener.local_addr().map_err(|e| e.to_string())?;
    println!("ecs-commission: page on http://{local}/");
    let stop = async {
        let mut term =
            tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()).ok();
        tokio::select! {
            _ = tokio::signal::ctrl_c() => {}
            _ = async { match term.as_mut() { Some(t) => { t.recv().await; } None => std::future::pending::<()>().await } } => {}
        }
    };
    // On a signal the tool ends at once (the drives' hold runs out by itself).
    tokio::select! {
        r = axum::serve(listener, router) => r.map_err(|e| e.to_string()),
        () = stop => Ok(()),
    }
}
