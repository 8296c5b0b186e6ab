"""`deepphy play`: a person plays an environment's tasks in the browser, recorded as a run
beside the models' (model `human:NAME`), and anyone can watch a recorded attempt again.

human.py    the person as a `ModelHandle`: requests wait on a desk for the page's answer;
            answers are journaled, so a play stopped mid-attempt resumes with nothing lost
session.py  the play: the scheduler of `deepphy run`, one episode at a time, in-process
server.py   aiohttp: the page, its state over Server-Sent Events, answers, prompt images
replay.py   an attempt simulated again from its recorded actions, as pictures (`film`)
static/     the pages: play (controls per kind of action space) and replay
"""
