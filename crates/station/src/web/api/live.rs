//! The station's status now and the live event stream (server-sent events
//! with catch-up), both from the hub.

use super::*;

pub(super) async fn status(
    State(app): State<App>,
    headers: HeaderMap,
) -> ApiResult<axum::Json<Value>> {
    authorize(&app, &headers, Role::Operator, false)?;
    let mut status =
        serde_json::to_value(app.hub.status()).map_err(|e| ApiError::internal(e.to_string()))?;
    status["active"] = json!(app.runner.active());
    status["prompt"] = json!(app.runner.prompt());
    status["simulated"] = json!(app.runner.simulated());
    status["station"] = json!(app.runner.station().0.station);
    Ok(axum::Json(status))
}

#[derive(Deserialize)]
pub(super) struct Since {
    since: Option<u64>,
}

/// Server-sent events: every engine event as JSON, `id` = its sequence
/// number. A browser that reconnects sends `Last-Event-ID` (or `?since=N`)
/// and first gets what it missed. One-second values are decimated to at
/// most one per 100 ms per browser (a fast virtual bench makes hundreds).
pub(super) async fn events(
    State(app): State<App>,
    headers: HeaderMap,
    Query(q): Query<Since>,
) -> ApiResult<Sse<impl Stream<Item = Result<SseEvent, Infallible>>>> {
    authorize(&app, &headers, Role::Operator, false)?;
    let last = headers
        .get("last-event-id")
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.parse::<u64>().ok())
        .or(q.since)
        .unwrap_or(0);
    let rx = app.hub.subscribe();
    let backlog = app.hub.since(last);
    struct Feed {
        backlog: std::vec::IntoIter<Arc<crate::web::hub::HubEvent>>,
        rx: tokio::sync::broadcast::Receiver<Arc<crate::web::hub::HubEvent>>,
        closing: tokio::sync::watch::Receiver<bool>,
        last: u64,
        last_values: Option<Instant>,
    }
    let feed = Feed {
        backlog: backlog.into_iter(),
        rx,
        closing: app.hub.closing(),
        last,
        last_values: None,
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
