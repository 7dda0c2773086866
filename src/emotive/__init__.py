"""emotive: make virtual agents move with emotion.

Conventions used everywhere in the package (house style):

* Quaternions are unit versors stored real part first: ``(w, x, y, z)``.
* Units are metres, Y is up and the ground is the XZ plane; files in centimetres are
  converted when they are read.
* Array shapes use the legend ``B`` = batch, ``T`` = frames, ``J`` = joints, ``C`` = channels.
"""

__version__ = "0.1.0"
