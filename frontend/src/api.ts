// Talking to the API, and the small helpers every part of the page uses.

export type Json = any; // eslint-disable-line @typescript-eslint/no-explicit-any

export const $ = <T extends Element = HTMLElement>(sel: string): T => {
  const el = document.querySelector<T>(sel);
  if (!el) throw new Error(`missing element ${sel}`);
  return el;
};

export class ApiError extends Error {
  constructor(public status: number, public detail: Json) {
    super(typeof detail === "string" ? detail : `HTTP ${status}`);
  }
}

/** A JSON request (a FormData body goes as multipart, a Blob as its type); throws ApiError with the
 *  API's detail. */
export async function api(path: string, init?: RequestInit): Promise<Json> {
  const json = typeof init?.body === "string"; // a FormData or Blob body says its own type
  const res = await fetch(path, { ...init, headers: json ? { "Content-Type": "application/json" } : undefined });
  const text = await res.text();
  let body: Json = null;
  try {
    body = text ? JSON.parse(text) : null;
  } catch {
    body = text; // a proxy's HTML error page: show it as text
  }
  if (!res.ok) throw new ApiError(res.status, body?.detail ?? body ?? `HTTP ${res.status}`);
  return body;
}

export const post = (path: string, body?: Json): Promise<Json> =>
  api(path, { method: "POST", body: body === undefined ? undefined : JSON.stringify(body) });

export const esc = (s: unknown): string =>
  String(s ?? "").replace(/[&<>"']/g, (c) => ({ "&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;", "'": "&#39;" })[c]!);
export const pct = (x: number | null | undefined): string => (x == null ? "–" : `${(100 * x).toFixed(1)} %`);
export const secs = (x: number | null | undefined): string => (x == null ? "–" : `${x.toFixed(2)} s`);
export const sleep = (ms: number): Promise<void> => new Promise((resolve) => setTimeout(resolve, ms));

/** The message of any error, for a status line. */
export const messageOf = (e: unknown): string =>
  e instanceof ApiError
    ? (Array.isArray(e.detail) ? e.detail.map((d: Json) => d.msg).join("; ") : String(e.detail))
    : String(e);
