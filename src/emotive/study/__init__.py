"""Perceptual studies: the seed papers' web studies with real observers.

A study is a folder: ``study.toml`` (the design: stimuli, conditions, questions,
counterbalancing, attention checks, consent text, completion code), ``stimuli/`` (one GLB per
stimulus, shown looping by the participant page, and ``readings.json``, the perceived-emotion
classifier's reading of each), and by default ``study.db`` (SQLite in WAL mode).

* :mod:`emotive.study.config` reads and checks ``study.toml``;
  :mod:`emotive.study.templates` writes the three designs of the papers (``gaits``,
  ``affect-grid``, ``sources``);
* :mod:`emotive.study.design` turns a participant's join order into their plan (condition,
  Latin-square order, repeats, attention checks);
* :mod:`emotive.study.stimuli` makes the stimuli (emotive's generators with a seed, or given
  BVH/GLB files);
* :mod:`emotive.study.db` and :mod:`emotive.study.store` keep participants and responses
  (SQLAlchemy 2, Alembic migrations; SQLite or PostgreSQL);
* :mod:`emotive.study.app` is the HTTP server (FastAPI): participant page, participant API,
  admin API; :mod:`emotive.study.faults` tells its storage faults (answered 503) from bugs
  and keeps what ``/api/health`` reports;
* :mod:`emotive.study.simulate`, :mod:`emotive.study.export` and :mod:`emotive.study.analyze`
  are the commands ``emotive study simulate|export|analyze``; :mod:`emotive.study.simulate_wait`
  is how the simulation retries and waits for its server until its deadline.

Nothing is imported here: the server's and the statistics' libraries load with the module
that needs them.
"""
