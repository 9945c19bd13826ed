# A stand-in for a robot's node: a real ROS node (it joins the ROS graph, and holds the parameters
# its launch gives it), saying hello with its arguments, then ticking until signalled.  It exits
# quietly on SIGINT (how the supervisor stops nodes) even when the signal comes while Python is
# still starting (before the handler is set): no KeyboardInterrupt traceback in its log.
try:
    import signal
    import sys

    signal.signal(signal.SIGINT, lambda *_: sys.exit(0))
    print("sleeper started", " ".join(sys.argv[1:]), flush=True)
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    rclpy.init(args=sys.argv, signal_handler_options=SignalHandlerOptions.NO)
    # Its name and namespace as launched (__node, __ns); its parameters from the launch's files.
    node = rclpy.create_node("sleeper", automatically_declare_parameters_from_overrides=True)
    ticks = [0]

    def tick() -> None:
        ticks[0] += 1
        print(f"tick {ticks[0]}", flush=True)

    node.create_timer(0.5, tick)
    try:
        rclpy.spin(node)  # its parameter services answer, as any node's
    finally:  # leave the graph at once, as a node that shuts down does
        node.destroy_node()
        rclpy.try_shutdown()
except KeyboardInterrupt:
    pass
