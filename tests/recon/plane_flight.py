"""The plane flight: six nadir views of a textured plane, 4 m apart from 30 m, and the options that reconstruct it
through the whole pipeline at small sizes; :class:`Run` records which stages a run of it ran."""

from recon.run.pipeline import Recon, ReconOptions
from recon.run.stages import STAGES
from recon.sfm.options import SfmOptions
from recon.surface.dense import DenseOptions

CENTRES = [(x, y, 30.0) for y in (0.0, 4.0) for x in (0.0, 4.0, 8.0)]
# every 2nd photo mapped (view_0, view_2, view_4 and the last, view_5), view_1 and view_3 registered afterwards; a
# Poisson octree of depth 8 (default 10) is fine enough for a plane seen at 320 px, and 5x faster (1.5 s, not 7 s)
OPTIONS = ReconOptions(sfm=SfmOptions(max_num_features=2048, every_kth=2, num_threads=2),
                       dense=DenseOptions(max_image_size=320, num_threads=2), poisson_depth=8)


class Run:
    """A Recon run of ``flight`` (photos, geotags) into ``scene`` that records which stage functions ran, the log
    and the progress reports."""

    def __init__(self, flight, scene, options=OPTIONS):
        self.ran, self.logs, self.progress = [], [], []
        self.recon = Recon(flight["photos"], flight["geotags"], scene, options, log=self.logs.append,
                           progress=lambda *report: self.progress.append(report))
        for stage in STAGES:
            body = getattr(self.recon, f"stage_{stage}")
            setattr(self.recon, f"stage_{stage}", self.spy(stage, body))
        self.recon.run()

    def spy(self, stage, body):
        def run():
            self.ran.append(stage)
            body()
        return run
