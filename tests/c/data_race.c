/* A deliberate data race: the control of the ThreadSanitizer test in tests/c_abi.rs, which must
 * see this program reported before it trusts a clean run of threads.c built the same way. */
#include <pthread.h>
#include <stdio.h>

static int counter;

static void *bump(void *arg) {
    int i;
    (void)arg;
    for (i = 0; i < 100000; i++) counter++;
    return NULL;
}

int main(void) {
    pthread_t a, b;
    pthread_create(&a, NULL, bump, NULL);
    pthread_create(&b, NULL, bump, NULL);
    pthread_join(a, NULL);
    pthread_join(b, NULL);
    printf("%d\n", counter);
    return 0;
}
