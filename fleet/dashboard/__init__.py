"""`fleet dashboard`: the fleet on a local web page, live from the Zenoh network.

live.py keeps the fleet's state current from what the agents publish (its model is the
FleetView of `fleet status`); server.py serves a static page (static/) and streams that state
to it as server-sent events.
"""
