# The Crossroads API (and, with another command, a Ray node) in one image.
FROM python:3.11-slim
WORKDIR /app
RUN apt-get update && apt-get install -y --no-install-recommends make && rm -rf /var/lib/apt/lists/*
COPY requirements.lock ./
# torch==2.13.0 from PyPI is a CUDA build; the CPU build is enough for inference and evaluation.
RUN pip install --no-cache-dir --extra-index-url https://download.pytorch.org/whl/cpu -r requirements.lock
COPY backend ./backend
COPY scenarios ./scenarios
COPY models ./models
RUN pip install --no-cache-dir --no-deps -e backend
ENV CROSSROADS_SCENARIOS_DIR=/app/scenarios
EXPOSE 8000
CMD ["crossroads", "serve", "--host", "0.0.0.0", "--port", "8000"]
