"""Who may come into the endpoint: pure rules, without socket or ROS.

gate (Gate: the limits on clients at connect, and a WebSocket client's upgrade request), room (who makes room when
the endpoint is full: SlotUse, Suspects, to_evict), auth (AuthGuard: the shared token, with a back-off per address),
web_clients (which web pages and proxies may open a WebSocket, and from where) and throttle (LogThrottle: one log
line for what may recur very often, such as connections turned away).

This file imports nothing: bridge.settings checks addresses by web_clients, and the gate reads bridge.config, which
is made from bridge.settings, so loading the gate here would close a circle. Import from the modules."""
