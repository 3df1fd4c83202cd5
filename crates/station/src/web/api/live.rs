//! The station's status now and the live event stream (server-sent events
//! with catch-up), both from the hub.

use super::schema::{ErrorBody, FleetStation, Saved, StatusReply};
use super::{
    ApiError, ApiResult, App, Arc, Bytes, Deserialize, Duration, HeaderMap, Infallible, Instant,
    Json, KeepAlive, Path, Query, QueryRejection, Role, Sse, SseEvent, State, Stream, auth,
    authorize, blocking, header, query_error, store,
};

/// The station now: run, step, rate, supplies, interlocks, modules, the board.
#[utoipa::path(get, path = "/api/status", tag = "live",
    security(("session" = [])),
    responses(
        (status = 200, description = "the station now", body = StatusReply),
        (status = 401, description = "not logged in", body = ErrorBody),
    ))]
pub(super) async fn status(
    State(app): State<App>,
    headers: HeaderMap,
) -> ApiResult<Json<StatusReply>> {
    authorize(&app, &headers, Role::Operator, false).await?;
    let mut snapshot = app.hub.status();
    // The runner's prompt is the one waiting now (the hub's may be answered).
    snapshot.prompt = app.runner.prompt();
    let run = app.runner.store_health();
    let store = super::schema::StoreHealthReply {
        up: app.metrics.store_answering() && run.as_ref().is_none_or(|h| h.up),
        queue_events: run.as_ref().map_or(0, |h| h.depth),
        queue_age_s: run.as_ref().map_or(0.0, |h| h.age_s),
        last_error: run.map(|h| h.last_error).unwrap_or_default(),
    };
    Ok(Json(StatusReply {
        snapshot,
        active: app.runner.active(),
        simulated: app.runner.simulated(),
        station: app.runner.station().0.station,
        store,
    }))
}

#[derive(Deserialize, utoipa::IntoParams)]
#[into_params(parameter_in = Query)]
pub(super) struct Since {
    /// Catch up from after this event's number (as `Last-Event-ID`).
    since: Option<u64>,
}

/// Server-sent events: every engine event as JSON, `id` = its sequence
/// number. A browser that reconnects sends `Last-Event-ID` (or `?since=N`)
/// and first gets what it missed. One-second values are decimated to at
/// most one per 100 ms per browser (a fast virtual bench makes hundreds).
#[utoipa::path(get, path = "/api/events", tag = "live",
    security(("session" = [])),
    params(Since, ("last-event-id" = Option<u64>, Header, description = "the last event seen")),
    responses(
        (status = 200, description = "the engine's events, one JSON object each (`event` names its kind); the stream stays open", content_type = "text/event-stream", body = String),
        (status = 400, description = "a bad query string (`since` is a whole number from 0)", body = ErrorBody),
        (status = 401, description = "not logged in", body = ErrorBody),
    ))]
pub(super) async fn events(
    State(app): State<App>,
    headers: HeaderMap,
    q: Result<Query<Since>, QueryRejection>,
) -> ApiResult<Sse<impl Stream<Item = Result<SseEvent, Infallible>>>> {
    authorize(&app, &headers, Role::Operator, false).await?;
    let Query(q) = q.map_err(query_error)?;
    let last = headers
        .get("last-event-id")
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.parse::<u64>().ok())
        .or(q.since)
        .unwrap_or(0);
    let rx = app.hub.subscribe();
    let backlog = app.hub.since(last);
    // The stream ends with its session (a logout or the user's removal on
    // any server of the fleet): checked every second.
    let token = headers
        .get(header::COOKIE)
        .and_then(|v| v.to_str().ok())
        .and_then(auth::session_token)
        .unwrap_or_default();
    struct Feed {
        backlog: std::vec::IntoIter<Arc<crate::web::hub::HubEvent>>,
        rx: tokio::sync::broadcast::Receiver<Arc<crate::web::hub::HubEvent>>,
        closing: tokio::sync::watch::Receiver<bool>,
        last: u64,
        last_values: Option<Instant>,
        app: App,
        token: String,
        check: tokio::time::Interval,
    }
    let mut check = tokio::time::interval(Duration::from_secs(1));
    check.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let feed = Feed {
        backlog: backlog.into_iter(),
        rx,
        closing: app.hub.closing(),
        last,
        last_values: None,
        app: app.clone(),
        token,
        check,
    };
    let stream = futures_util::stream::unfold(feed, |mut feed| async move {
        loop {
            if *feed.closing.borrow() {
                return None;
            }
            let next = match feed.backlog.next() {
                Some(e) => e,
                None => {
                    let received = tokio::select! {
                        received = feed.rx.recv() => received,
                        _ = feed.closing.changed() => return None,
                        _ = feed.check.tick() => {
                            let token = feed.token.clone();
                            let open = blocking(&feed.app, move |app| {
                                Ok(app.sessions.get(&app.store, &token).is_some())
                            })
                            .await
                            .unwrap_or(true);
                            if !open {
                                return None;
                            }
                            continue;
                        }
                    };
                    match received {
                        Ok(e) => e,
                        Err(tokio::sync::broadcast::error::RecvError::Lagged(_)) => continue,
                        Err(tokio::sync::broadcast::error::RecvError::Closed) => return None,
                    }
                }
            };
            if next.seq <= feed.last {
                continue;
            }
            if next.kind == "values" {
                let now = Instant::now();
                if feed
                    .last_values
                    .is_some_and(|t| now.duration_since(t) < Duration::from_millis(100))
                    && feed.backlog.len() == 0
                {
                    continue;
                }
                feed.last_values = Some(now);
            }
            feed.last = next.seq;
            let event = SseEvent::default()
                .id(next.seq.to_string())
                .event(next.kind.clone())
                .data(next.json.clone());
            return Some((Ok(event), feed));
        }
    });
    Ok(Sse::new(stream).keep_alive(KeepAlive::default()))
}

/// Every station of the fleet on this store: state, current run, progress,
/// today's first-pass yield.
#[utoipa::path(get, path = "/api/fleet", tag = "live",
    security(("session" = [])),
    responses(
        (status = 200, description = "the stations, by id", body = Vec<FleetStation>),
        (status = 401, description = "not logged in", body = ErrorBody),
    ))]
pub(super) async fn fleet(
    State(app): State<App>,
    headers: HeaderMap,
) -> ApiResult<Json<Vec<FleetStation>>> {
    authorize(&app, &headers, Role::Operator, false).await?;
    let this = app.runner.station().0.station;
    let rows = blocking(&app, |app| {
        let store = store(app)?;
        let mut rows = Vec::new();
        for r in store.stations()? {
            // The run by its label, the id beside it.
            let label = match &r.beat.run_id {
                Some(id) => store.run(id)?.map(|run| run.label()),
                None => None,
            };
            rows.push((r, label));
        }
        Ok(rows)
    })
    .await?;
    Ok(Json(
        rows.into_iter()
            .map(|(r, run_label)| FleetStation {
                run_label,
                this_station: r.beat.station == this,
                station: r.beat.station,
                state: r.beat.state,
                kind: r.kind,
                run_id: r.beat.run_id,
                steps_done: r.beat.progress.map(|p| p.0),
                steps_total: r.beat.progress.map(|p| p.1),
                address: r.beat.address,
                last_seen: r.last_seen,
                tested_today: r.tested_today,
                passed_today: r.passed_today,
                first_pass_yield: (r.tested_today > 0)
                    .then(|| r.passed_today as f64 / r.tested_today as f64),
                last_run_outcomes: r.last_run_outcomes.into_iter().collect(),
            })
            .collect(),
    ))
}

/// Take an offline station out of the Fleet list (an admin; audited): its
/// runs stay, and it comes back when it runs again. A live station, or the
/// one answering, is not retired.
#[utoipa::path(delete, path = "/api/fleet/{station}", tag = "live",
    security(("session" = [], "csrf" = [])),
    params(("station" = String, Path, description = "the station's name")),
    responses(
        (status = 200, description = "retired", body = Saved),
        (status = 401, description = "not logged in", body = ErrorBody),
        (status = 403, description = "no or a wrong CSRF token, or not an admin", body = ErrorBody),
        (status = 404, description = "no such station in the list", body = ErrorBody),
        (status = 409, description = "the station is live, or is this one", body = ErrorBody),
    ))]
pub(super) async fn retire_station(
    State(app): State<App>,
    headers: HeaderMap,
    Path(station): Path<String>,
    _body: Bytes,
) -> ApiResult<Json<Saved>> {
    let session = authorize(&app, &headers, Role::Admin, true).await?;
    if station == app.runner.station().0.station {
        return Err(ApiError::conflict(format!(
            "'{}' is this station; retire it from another station's page once it is offline",
            spinbench_engine::bounds::shown(&station)
        )));
    }
    let asked = station.clone();
    let (listed, retired) = blocking(&app, move |app| {
        let store = store(app)?;
        let listed = store.stations()?.iter().any(|s| s.beat.station == asked);
        let retired = listed && store.retire_station(&asked, &session.user)?;
        Ok((listed, retired))
    })
    .await?;
    match (listed, retired) {
        (false, _) => Err(ApiError::not_found(format!(
            "no station '{}' in the Fleet list",
            spinbench_engine::bounds::shown(&station)
        ))),
        (true, false) => Err(ApiError::conflict(format!(
            "station '{}' is live (heard within 10 s): stop its server first",
            spinbench_engine::bounds::shown(&station)
        ))),
        (true, true) => Ok(Json(Saved { saved: true })),
    }
}
