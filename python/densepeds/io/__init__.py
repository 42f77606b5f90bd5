"""Reading and writing what a run consumes and produces: frame sources (videos, image folders,
MOTChallenge sequences, live cameras), MOTChallenge det/gt/track files, the annotated video."""
