# Set-up and entry points. `make pick` and `make test` create the environment first.
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
APT_PACKAGES := libusb-1.0-0 libegl1 libegl-mesa0 libgl1-mesa-dri libgl1 chromium

.PHONY: env apt pick test lint objects segmenter benchmark-perception clean

env: apt $(STAMP)

# System packages: open3d needs libusb; VTK renders headless through EGL; the viewer test screenshots
# meshcat with headless chromium.
apt:
	@missing=$$(for p in $(APT_PACKAGES); do dpkg -s $$p >/dev/null 2>&1 || echo $$p; done); \
	if [ -n "$$missing" ]; then \
		echo "installing system packages: $$missing"; \
		SUDO=$$( [ "$$(id -u)" = 0 ] || echo sudo ); \
		$$SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq $$missing >/dev/null; \
	fi

$(STAMP): pyproject.toml
	python3 -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e ".[dev,cluster,benchmark]"
	touch $(STAMP)

pick: env
	$(PY) scripts/pick.py $(ARGS)

test: env
	DRAKE_DEPRECATION_RUNTIME_SEVERITY=error $(PY) -m pytest -q $(ARGS)

lint: env
	$(VENV)/bin/ruff check .
	$(VENV)/bin/ruff format --check .

objects: env
	$(PY) scripts/generate_objects.py

# Renders the synthetic training frames (data/, not versioned) and retrains models/segmenter.pt (~15 min, 2 cores).
segmenter: env
	$(PY) scripts/generate_segmentation_data.py --jobs 2
	$(PY) scripts/generate_segmentation_data.py --jobs 2 --crowded --frames 400 --seed 2 --out data/segmentation/crowded.npz
	$(PY) scripts/generate_segmentation_data.py --jobs 2 --split wide --frames 400 --seed 3 --out data/segmentation/wide.npz
	$(PY) scripts/train_segmenter.py --data data/segmentation/train.npz --out data/segmentation/segmenter_single.pt
	$(PY) scripts/train_segmenter.py --data data/segmentation/train.npz data/segmentation/crowded.npz \
		--init data/segmentation/segmenter_single.pt --epochs 10 --learning-rate 5e-4 \
		--out data/segmentation/segmenter_crowded.pt
	$(PY) scripts/train_segmenter.py \
		--data data/segmentation/train.npz data/segmentation/crowded.npz data/segmentation/wide.npz \
		--init data/segmentation/segmenter_crowded.pt --epochs 10 --learning-rate 5e-4

benchmark-perception: env
	$(PY) scripts/benchmark_perception.py --scenes 60 --json perception.json

clean:
	rm -rf $(VENV) *.egg-info .pytest_cache
