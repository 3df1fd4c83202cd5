"""The MES path through a client generated from the station's own OpenAPI
document by openapi-python-client (a mainstream generator, not ours): log
in, start a run, answer every prompt, wait for the end, read the run, and
download its PDF report. Run by crates/station/tests/mes_client.rs, which
generates the client (scripts/mes/generator.yaml) and checks what this
prints and writes.

    python mes_path.py CLIENT_DIR BASE_URL USER PASSWORD PLAN SERIALS_JSON PDF_OUT

With USER "token:", PASSWORD is an API token's secret: the client sends it
as `Authorization: Bearer` (a machine client: no login, no cookie, no
CSRF token).

Prints one JSON line: the run, its state, the prompts answered, each
instrument's outcome, and every /api/status answer's state as the
generated model parsed it (a field the model cannot parse raises here).
"""

import json
import sys
import time


def logged_in(base, user, password, Client, AuthenticatedClient, login, Login, SessionReply):
    """A person's client: logged in, its cookie and CSRF token carried."""
    anonymous = Client(base_url=base, raise_on_unexpected_status=True)
    answer = login.sync_detailed(client=anonymous, body=Login(user=user, password=password))
    if not isinstance(answer.parsed, SessionReply):
        raise SystemExit(f"login: {answer.status_code} {answer.content!r}")
    cookie = answer.headers["set-cookie"].split(";", 1)[0]
    name, value = cookie.split("=", 1)
    # The session is a cookie and the CSRF token a header (both documented
    # as security schemes): the generator's authenticated client carries them.
    return AuthenticatedClient(
        base_url=base,
        token=answer.parsed.csrf,
        prefix="",
        auth_header_name="X-CSRF-Token",
        cookies={name: value},
        raise_on_unexpected_status=True,
        timeout=None,
    )


def main() -> int:
    client_dir, base, user, password, plan, serials, pdf_out = sys.argv[1:8]
    sys.path.insert(0, client_dir)
    from spinbench_mes import AuthenticatedClient, Client
    from spinbench_mes.api.live import status
    from spinbench_mes.api.runs import answer_prompt, report, run, start_run
    from spinbench_mes.api.session import login
    from spinbench_mes.models import (
        Login,
        PromptAnswer,
        ReportFormatName,
        RunDetail,
        RunId,
        SessionReply,
        StartRun,
        StartRunSerials,
        StatusReply,
    )

    if user == "token:":
        # A machine client: the generator's authenticated client sends the
        # token as the documented bearer scheme, and nothing else.
        client = AuthenticatedClient(
            base_url=base,
            token=password,
            raise_on_unexpected_status=True,
            timeout=None,
        )
    else:
        client = logged_in(base, user, password, Client, AuthenticatedClient, login, Login, SessionReply)

    wanted = StartRunSerials()
    wanted.additional_properties = json.loads(serials)
    started = start_run.sync_detailed(client=client, body=StartRun(plan=plan, serials=wanted))
    if not isinstance(started.parsed, RunId):
        raise SystemExit(f"start: {started.status_code} {started.content!r}")
    run_id = started.parsed.run_id

    prompts = 0
    states = []
    deadline = time.monotonic() + 300
    while True:
        now = status.sync(client=client)
        if not isinstance(now, StatusReply):
            raise SystemExit(f"status: {now!r}")
        states.append(str(now.state.value) if now.state else None)
        if isinstance(now.prompt, str) and now.prompt:
            done = answer_prompt.sync_detailed(client=client, body=PromptAnswer(proceed=True))
            if done.status_code != 200:
                raise SystemExit(f"prompt: {done.status_code} {done.content!r}")
            prompts += 1
        elif now.active is None and now.run_id == run_id and now.ended:
            break
        if time.monotonic() > deadline:
            raise SystemExit(f"the run did not end in 300 s: {now.to_dict()}")
        time.sleep(0.05)

    detail = run.sync(run_id, client=client)
    if not isinstance(detail, RunDetail):
        raise SystemExit(f"run: {detail!r}")
    pdf = report.sync_detailed(run_id, ReportFormatName.PDF, client=client)
    if pdf.status_code != 200:
        raise SystemExit(f"report: {pdf.status_code} {pdf.content!r}")
    # Raw bytes, documented in OpenAPI 3.1's way (the media type, no
    # schema): the generated client hands back the response's content.
    payload = pdf.content
    if pdf.headers.get("content-type") != "application/pdf":
        raise SystemExit(f"report: content type {pdf.headers.get('content-type')!r}")
    with open(pdf_out, "wb") as f:
        f.write(payload)
    print(
        json.dumps(
            {
                "run_id": run_id,
                "state": detail.state.value,
                "prompts": prompts,
                "outcomes": sorted({r.outcome.value for r in detail.results}),
                "serials": sorted({r.serial for r in detail.results}),
                "status_states": sorted({s for s in states if s}),
                "pdf_bytes": len(payload),
            }
        )
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
