// The page's state, shared by its modules, and the few helpers everything uses.

export const SVG_NS = 'http://www.w3.org/2000/svg';
export const EARTH_RADIUS_M = 6378137;
export const ACTIVE_TARGET_STATES = new Set(['pending', 'assigned']);
export const MAX_ALERTS = 6;

export const state = {
  uavs: [],            // the latest snapshot's UAVs (ground-cli uavs --json + trail, link_lost)
  mission: null,       // the followed mission (send-targets --json + target_states)
  targets: [],         // the operator's target list: {lat, lon, alt}
  excluded: new Set(), // live UAVs the operator took out of the team
  statuses: [],        // {seq, time, uav, text, severity, count}
  alerts: [],
  lastOf: new Map(),
  lastSeq: 0,   // each UAV's latest status entry
  origin: null,        // {lat, lon}: the local east-north frame's origin
  view: null,          // the SVG viewBox in metres {x, y, w, h}
  autoFit: true,
  ws: null,
  nextId: 1,
  seenMission: null,
  ownMissions: new Set(), // missions this page sent (a mission from elsewhere is announced)
  reconnects: 0,          // how often the socket dropped and was opened again
};

export const $ = (selector) => document.querySelector(selector);
export const token = new URLSearchParams(location.search).get('token');

export function withToken(path) {
  return token ? `${path}${path.includes('?') ? '&' : '?'}token=${encodeURIComponent(token)}` : path;
}
