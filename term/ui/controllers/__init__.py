"""The controllers the app owns: each is built from the parts it acts on (the station, the clock, the config, a
narrow host for what only the app can do: a worker, a screen, a key's path) and driven by station events and the
render tick. They hold no Textual widget; the app turns their work into screens and messages.

- ``downloads.DownloadController``: the flash-log download (F5), its retries and resumes, the CSV it saves;
- ``lessons.LessonController``: the lessons, the "show me" autopilot and the demo (term --sim);
- ``params.ParamsController``: the board's parameter list after Hello, apply-on-connect, the parameter screen's
  requests.
"""
