// What the page knows, shared by its modules. HTTP is the source of truth: this is the latest reading.

export const page = {
  /** GET /access: {authenticated, open_reads}; null before the first answer. */
  access: null,
  /** "ok" or "lost": whether the service answers (document.body.dataset.connection mirrors it). */
  connection: "ok",
  /** The latest GET /station. */
  station: null,
  /** The id of the session the station runs (null when none). */
  running: null,
  /** The id of the session shown in the Session panel, and its latest document. */
  current: null,
  session: null,
  /** Whether the operator chose the shown session (else the page follows the running or latest one). */
  chosen: false,
  /** The plans' parameter schemas by kind (GET /plans). */
  plans: new Map(),
  /** The latest page of GET /sessions (newest first). */
  history: [],
  /** Set from the click on Start until the service has answered: the camera is not asked meanwhile. */
  starting: false,
  /** Actions (start, pause, resume ...) in flight, and a count that changes with each: a reading taken
   * before an action answered may be stale, and nothing that a stale reading suggests is asked for. */
  actions: 0,
  epoch: 0,
  /** Set while this page's request to take the arm to its reference pose runs: the camera is not asked
   * meanwhile (the worker moves the arm and answers 409 to a snapshot). */
  moving: false,
};

/** Whether this client may act (it holds the token) and the service answers. */
export const canAct = () => page.connection === "ok" && page.access?.authenticated === true;

/** Whether this client may start or resume what moves the arm: it runs on the station itself, or the
 * service allows remote motion (GET /access's `motion`). */
export const mayMove = () => page.access?.motion === true;

/** Whether sessions of `kind` drive the station's devices (an unknown plan counts as driving them). */
export const drives = (kind) => {
  const plan = page.plans.get(kind);
  return !plan || plan.needs.length > 0;
};

/** Whether this client may read the station at all. */
export const canRead = () => page.access !== null && (page.access.authenticated || page.access.open_reads);
