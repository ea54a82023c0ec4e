"""MCAP recording of a simulation, one part per job: ``schemas`` (what each topic's messages are),
``encoding`` (protobuf templates filled by one compiled pass), ``writer`` (chunks, index, summary,
the file always readable), ``recorder`` (decimation, signals, metadata: ``McapRecorder``),
``topics`` (a simulation's state → numeric topics), ``buffer`` (the engines' samples written in
blocks), ``frames`` (world → parent-relative poses), ``read`` (decoding a recording back with the
published decoders) and ``inspect`` (``sms inspect`` and ``--repair``)."""
