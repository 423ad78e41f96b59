"""The operator station: a web page served by the cell daemon, and Prometheus metrics.

Layering: the station sits between the command line and the cell runtime. It sees the daemon only
through :class:`~controller.station.web_app.DaemonPort` (status, the control requests of
``seamguide ctl``, the records folder), so the page and ``ctl`` have the same semantics.
"""
