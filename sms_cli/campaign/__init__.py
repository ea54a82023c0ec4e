"""``sms campaign``: Monte-Carlo dispersions and parameter sweeps of a mission.

A campaign is a mission file with a ``campaign:`` section (usually a file that ``extends:`` a
shipped mission). Each run is the mission with the campaign's dispersions applied at dotted
paths, run through the stages the campaign names, on a local Dask cluster or a remote scheduler.

Package layout, one job per module:

- ``schema``       the ``campaign:`` section (designs, dispersions, distributions, execution)
- ``paths``        dotted paths into a mission tree: resolve, set, did-you-mean, file:line
- ``dispersions``  per-run samples: seeding (SeedSequence keyed by run and dispersion name), designs
- ``runner``       one run in-process: dispersed mission → stages → metrics, read-back parameters
- ``sandbox``      a run in a child process with a timeout (a crash or hang costs one attempt)
- ``execute``      submit runs to Dask as they complete, retries, lost workers, Ctrl-C
- ``store``        the results folder: campaign.json, manifest.jsonl, metrics/*.parquet, resume
- ``stats``        statistics, Wilson intervals, rank correlations → results.json ``campaign``
- ``requirements`` campaign-level requirements (pass rates, correlations) for ``sms check``
- ``plots``        histograms and metric-against-parameter figures
- ``stage``        the command: define → execute → store → statistics → plots

Results folder of a campaign (written by the client process only):

- ``campaign.json``   the resolved campaign: mission file and its SHA-256, entropy, design, the
                      parameters (name, path, distribution, nominal value, unit) and the run count
- ``manifest.jsonl``  append-only, one JSON line per attempt: run, attempt, status, seed, wall_s,
                      exit_status, message, worker, time
- ``metrics/part-*.parquet``  one row per finished run: ``run``, ``status``, ``exit_status``,
                      ``param.<name>`` (the value that ran, read back from the built model),
                      ``metric.<stage.path>`` (every number of the run's results sections),
                      ``req.<name>`` (the mission's requirements, pass = true)
- ``results.json``    section ``campaign``: statistics, pass rates, sensitivities, artefacts
- ``runs/<id>/``      what ``sms campaign rerun`` wrote for one run (its MCAP among them)
"""
